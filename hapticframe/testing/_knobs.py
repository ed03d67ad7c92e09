"""The kit's check of a spec's declared speed/accuracy knobs (issue 18)."""

from __future__ import annotations

from typing import Any

from pydantic import ValidationError

from hapticframe._knobs import knob_duplicates, knob_problems
from hapticframe._registry import Registry
from hapticframe._specs import PluginSpec
from hapticframe.testing._common import check
from hapticframe.testing._harness import CheckFailure

__all__ = ["check_knobs"]


def _bases(spec: PluginSpec) -> list[dict[str, Any]]:
    """The configs a knob's values are set on: the check config, and the defaults too when
    they validate (a model with a required field, a port, has no defaults to try)."""
    if not spec.check_config:
        return [{}]
    bases = [dict(spec.check_config)]
    try:
        spec.config.model_validate({})
    except ValidationError:
        return bases
    return [*bases, {}]


@check()
def check_knobs(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Each declared knob names a field of the config model (nested models included), its
    range lies inside the field's bounds, and every value it sweeps validates on the check
    config and on the defaults; no field is declared twice. A spec without knobs passes."""
    problems = [f"knob {field!r} is declared more than once"
                for field in knob_duplicates(spec.knobs)]
    bases = _bases(spec)
    for knob in spec.knobs:
        problems += knob_problems(spec.config, knob, bases)
    if problems:
        raise CheckFailure(
            f"{spec.kind} plugin {spec.name!r} ({spec.config.__name__}): " + "; ".join(problems)
            + " — fix the knobs=(...) of its spec"
        )
