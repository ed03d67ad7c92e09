"""Build an experiment's components, inputs first, and close them again.

Every component is built under a :class:`contextlib.ExitStack` that the caller owns: a
failure while building closes what was already built, and leaving the stack closes every
component in reverse build order, each ``close()`` guarded, so one that raises neither
leaves the others open nor hides the run's own outcome.
"""

from __future__ import annotations

import logging
import zlib
from collections.abc import Callable
from contextlib import ExitStack

import numpy as np

from ._components import Components
from ._config import ComponentEntry, Experiment
from ._errors import ExperimentError, HapticframeError, Issue, RunError
from .kinds import BuildContext, Component

__all__ = ["build_components", "component_rng"]

_log = logging.getLogger(__name__)

#: Receives ``(component id, exception)`` for each ``close()`` that raised.
CloseErrorHandler = Callable[[str, BaseException], None]


def component_rng(seed: int, component_id: str) -> np.random.Generator:
    """The generator of one component: independent streams per id, fixed by the seed."""
    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(zlib.crc32(component_id.encode("utf-8")),))
    )


def _log_close_error(component_id: str, exc: BaseException) -> None:
    _log.warning("closing %r failed: %s: %s", component_id, type(exc).__name__, exc)


def _closer(component: Component, on_error: CloseErrorHandler) -> Callable[[], None]:
    def close() -> None:
        try:
            component.close()
        except Exception as exc:  # one failing close must not keep the others open
            on_error(component.id, exc)

    return close


def build_components(
    experiment: Experiment,
    stack: ExitStack,
    *,
    progress: bool = True,
    on_close_error: CloseErrorHandler = _log_close_error,
) -> Components:
    """Import and construct every component, inputs first; ``stack`` closes them.

    Each built component's ``close()`` is pushed onto ``stack`` as soon as it is built;
    a ``close()`` that raises is passed to ``on_close_error`` (default: logged) and the
    others are still closed. ``progress`` is handed to each component
    (:attr:`BuildContext.progress`).

    Raises
    ------
    ExperimentError
        When a plugin rejects its configuration while being built (a ``ValueError`` or
        ``KeyError``; exit status 2).
    RunError
        When building fails otherwise (a device's ``OSError``, a ``TypeError`` in the
        plugin, a component of the wrong kind), naming the component (exit status 1).
    PluginImportError
        When an implementation cannot be imported.
    """
    scene = experiment.model.scene
    built = Components()
    for entry in experiment.components:
        factory = entry.registered.spec.load_factory()
        context = BuildContext(
            id=entry.id,
            rng=component_rng(experiment.seed, entry.id),
            inputs={name: built[name] for name in entry.inputs},
            scene=scene,
            progress=progress,
        )
        try:
            component = factory(entry.config, context)
        except (ValueError, KeyError) as exc:
            raise ExperimentError(experiment.file, [Issue(
                entry.path, f"cannot build {_named(entry)}: {exc}",
            )]) from exc
        except HapticframeError:
            raise
        except Exception as exc:
            raise RunError(f"cannot build {_named(entry)}: {type(exc).__name__}: {exc}") from exc
        if isinstance(component, Component):
            stack.callback(_closer(component, on_close_error))
        built.add(entry.id, entry.kind, component, plugin=entry.type)
    return built


def _named(entry: ComponentEntry) -> str:
    return f"{entry.id!r} ({entry.kind} {entry.type!r})"
