"""Plugin validators: checks across fields, components and the scene, run at ``validate``.

A plugin's spec names a validator (``validator="package.checks:check"``); :func:`run_validators`
calls it for each component with the component's validated config and a
:class:`ValidationContext`, and turns the :class:`Finding` records it yields into located
issues (errors) and warnings. Nothing is built: a validator reads configs, never loads a
model or opens a device.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from .._errors import Issue, PluginImportError
from .._kind import Kind
from ._load import LoadedFile

if TYPE_CHECKING:
    from ._validate import ComponentEntry

__all__ = ["ComponentView", "Finding", "ValidationContext", "run_validators"]


@dataclass(frozen=True)
class Finding:
    """One result of a plugin's validator.

    Parameters
    ----------
    message : str
        What is wrong and what to do, in one sentence or two (the component is named by
        the location; numbers with their units, estimates where a size is the problem).
    field : str
        The dotted config field it concerns (``"hinge_spacing_m"``), ``""`` for the whole
        component; it locates the message in the file.
    severity : ``"error"`` or ``"warning"``
        An error refuses the file (exit 2); a warning is reported and the file is valid
        (legal but suspicious).
    """

    message: str
    field: str = ""
    severity: Literal["error", "warning"] = "error"

    def __post_init__(self) -> None:
        if self.severity not in ("error", "warning"):
            raise ValueError(f"severity must be 'error' or 'warning', got {self.severity!r}")


@dataclass(frozen=True)
class ComponentView:
    """What a validator may read of a component: its id, kind, type and validated config."""

    id: str
    kind: Kind
    type: str
    config: Any
    inputs: tuple[str, ...] = ()


@dataclass(frozen=True)
class ValidationContext:
    """What a plugin's validator sees besides its own config.

    Attributes
    ----------
    id : str
        The component's id.
    inputs : mapping of str to ComponentView
        Its inputs, by id, in the file's order.
    components : mapping of str to ComponentView
        Every component of the experiment, by id.
    scene : Scene or None
        The validated scene (``scene.region``, ``scene.objects``, ``scene.material``).
    run : RunSettings
        The validated ``run`` section.
    """

    id: str
    inputs: Mapping[str, ComponentView]
    components: Mapping[str, ComponentView]
    scene: Any
    run: Any
    extra: Mapping[str, Any] = field(default_factory=dict)


def run_validators(
    entries: Iterable[ComponentEntry], model: Any, loaded: LoadedFile
) -> tuple[list[Issue], list[Issue]]:
    """Call every component's validator; returns ``(errors, warnings)`` as located issues."""
    entries = list(entries)
    views = {
        e.id: ComponentView(e.id, e.kind, e.type, e.config, tuple(e.inputs)) for e in entries
    }
    errors: list[Issue] = []
    warnings: list[Issue] = []
    for entry in entries:
        spec = entry.registered.spec
        if not spec.validator:
            continue
        try:
            validator = spec.load_validator()
        except PluginImportError as exc:
            errors.append(Issue(entry.path, str(exc), loaded.line_of(entry.path)))
            continue
        context = ValidationContext(
            id=entry.id,
            inputs={i: views[i] for i in entry.inputs if i in views},
            components=views,
            scene=getattr(model, "scene", None),
            run=getattr(model, "run", None),
        )
        for finding in validator(entry.config, context) or ():
            if not isinstance(finding, Finding):
                raise TypeError(
                    f"the validator of {spec.kind} plugin {spec.name!r} yielded "
                    f"{type(finding).__name__}, not a hapticframe.Finding"
                )
            path = f"{entry.path}.config.{finding.field}" if finding.field else entry.path
            line = loaded.line_of(path) or loaded.line_of(entry.path)
            issue = Issue(path, finding.message, line)
            (errors if finding.severity == "error" else warnings).append(issue)
    return errors, warnings
