"""The kit's check of the sizes a plugin's validator declares (issue 26 §3).

A validator declares every config field that sizes an allocation or a loop by yielding a
:class:`hapticframe.Size`; ``validate`` refuses an estimate over the core's limits. This
check sets each declared field to the extremes of its schema range, one at a time on the
check config, and requires each extreme to be refused (by the config model, by a finding,
or by its size) or, when accepted, to be built and driven as the kit drives its kind with
a traced peak of at most :data:`~hapticframe._config._sizes.MEMORY_LIMIT_BYTES`.
"""

from __future__ import annotations

import copy
import math
import sys
import tracemalloc
from collections.abc import Iterator, Mapping
from typing import Any, get_args

import annotated_types as at
import numpy as np
from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from hapticframe._config._checks import (
    ValidationContext,
    size_findings,
    validator_results,
)
from hapticframe._config._model import RunSettings
from hapticframe._config._sizes import MEMORY_LIMIT_BYTES, format_bytes
from hapticframe._kind import Kind
from hapticframe._registry import Registry
from hapticframe._specs import PluginSpec
from hapticframe.testing._common import check
from hapticframe.testing._harness import DEFAULT_SCENE, CheckFailure
from hapticframe.testing._spatial import _exercise
from hapticframe.threads import machine_cpus

__all__ = ["RUN_RANGE_FIELDS", "check_declared_sizes", "check_run_range_ends", "kit_context",
           "range_extremes"]

#: What the kit tries for an integer or a float whose range is open above.
_UNBOUNDED_INT = 2**62
_UNBOUNDED_FLOAT = 1e300


def kit_context(spec: PluginSpec) -> ValidationContext:
    """The context the kit validates a lone component in: the kit's scene, default run
    settings, no inputs."""
    return ValidationContext(id=spec.name, inputs={}, components={}, scene=DEFAULT_SCENE,
                             run=RunSettings(), extra={"command": "run"})


def _field(model: type[BaseModel], dotted: str) -> FieldInfo | None:
    """The field at ``dotted`` (nested models, optional ones included), or None."""
    info: FieldInfo | None = None
    current: Any = model
    for part in dotted.split("."):
        if not (isinstance(current, type) and issubclass(current, BaseModel)):
            return None
        info = current.model_fields.get(part)
        if info is None:
            return None
        options = [info.annotation, *get_args(info.annotation)]
        current = next((o for o in options if isinstance(o, type) and issubclass(o, BaseModel)),
                       None)
    return info


def range_extremes(info: FieldInfo) -> list[int | float]:
    """The ends of a numeric field's range: the closest legal values to each bound (an
    open bound's neighbour), and a huge value where the range is open above."""
    options = [info.annotation, *get_args(info.annotation)]
    integer = int in options and float not in options
    if not (integer or float in options):
        return []
    low: int | float | None = None
    high: int | float | None = None
    for item in info.metadata:
        bound: Any = getattr(item, type(item).__name__.lower(), None)
        if isinstance(item, at.Ge):
            low = bound
        elif isinstance(item, at.Gt):
            low = int(bound) + 1 if integer else math.nextafter(float(bound), math.inf)
        elif isinstance(item, at.Le):
            high = bound
        elif isinstance(item, at.Lt):
            high = int(bound) - 1 if integer else math.nextafter(float(bound), -math.inf)
    if high is None:
        high = _UNBOUNDED_INT if integer else _UNBOUNDED_FLOAT
    return [v for v in (low, high) if v is not None]


def _with(base: Mapping[str, Any], dotted: str, value: Any) -> dict[str, Any]:
    data = copy.deepcopy(dict(base))
    node = data
    *parents, last = dotted.split(".")
    for part in parents:
        child = node.get(part)
        node[part] = child = dict(child) if isinstance(child, dict) else {}
        node = child
    node[last] = value
    return data


def _refused(
    spec: PluginSpec, validator: Any, data: Mapping[str, Any], name: str
) -> str | None:
    """Why validation refuses field ``name`` of ``data`` (None when it is accepted): the
    config model, or an error of the validator (a finding or a size) located at that field
    or naming it. Other errors (a lone component lacks its inputs) do not refuse it."""
    try:
        config = spec.config.model_validate(dict(data))
    except ValidationError as exc:
        return f"the config model: {exc.errors()[0]['msg']}"
    findings, sizes = validator_results(validator, config, kit_context(spec), repr(spec.name))
    errors = [f.message for f in [*findings, *size_findings(sizes, findings)]
              if f.severity == "error" and (f.field == name or name in f.message)]
    return errors[0] if errors else None


def _peak_bytes(spec: PluginSpec, data: Mapping[str, Any], registry: Registry | None) -> int:
    """How far the process's peak memory rose while ``spec`` was built with ``data`` and
    driven as its kind: the growth of its peak resident set where the OS reports one
    (cheap), else the peak traced by :mod:`tracemalloc`."""
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        resource = None  # type: ignore[assignment]
    if resource is not None:
        # ru_maxrss is in KiB on Linux, in bytes on macOS.
        unit = 1 if sys.platform == "darwin" else 1024
        before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        _exercise(spec, registry, config=data)
        return (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * unit
    was_tracing = tracemalloc.is_tracing()  # pragma: no cover - Windows
    if not was_tracing:
        tracemalloc.start()
    tracemalloc.reset_peak()
    try:
        _exercise(spec, registry, config=data)
        return tracemalloc.get_traced_memory()[1]
    finally:
        if not was_tracing:
            tracemalloc.stop()


def _declared(spec: PluginSpec, validator: Any) -> Iterator[str]:
    base = spec.config.model_validate(dict(spec.check_config or {}))
    _, sizes = validator_results(validator, base, kit_context(spec), repr(spec.name))
    yield from dict.fromkeys(size.field for size in sizes)


@check()
def check_declared_sizes(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Each config field the validator declares with a :class:`hapticframe.Size` is refused
    at the extremes of its range, or built and driven there within the memory limit. A
    spec without a validator, or whose validator declares no size, passes."""
    if not spec.validator:
        return
    validator = spec.load_validator()
    base = dict(spec.check_config or {})
    problems: list[str] = []
    for name in _declared(spec, validator):
        info = _field(spec.config, name)
        if info is None:
            problems.append(f"a Size names {name!r}, which is no field of {spec.config.__name__}")
            continue
        for value in range_extremes(info):
            data = _with(base, name, value)
            if _refused(spec, validator, data, name) is not None:
                continue
            try:
                peak = _peak_bytes(spec, data, registry)
            except CheckFailure as exc:
                problems.append(f"{name} = {value!r} is accepted but fails when driven: {exc}")
                continue
            except (MemoryError, ValueError, RuntimeError) as exc:
                problems.append(f"{name} = {value!r} is accepted by validate but raised "
                                f"{type(exc).__name__} when driven: {exc}")
                continue
            if peak > MEMORY_LIMIT_BYTES:
                problems.append(f"{name} = {value!r} is accepted by validate but took "
                                f"{format_bytes(peak)} when driven (the limit is "
                                f"{format_bytes(MEMORY_LIMIT_BYTES)})")
    if problems:
        raise CheckFailure(
            f"{spec.kind} plugin {spec.name!r}: " + "; ".join(problems) + " — refuse such "
            "values in its validator (yield a hapticframe.Size with the estimate) or bound "
            "the field in its config model"
        )



#: Fields whose low range end a run meets (issue 36 §2), by the end of their name: a ramp
#: (``acceleration_m_per_s2``: too small and a movement never ends), a filter cutoff
#: (``cutoff_hz``: too small and the filter's coefficients are NaN) and a planner's depth
#: (``depth_m``: the robot refuses 0; a robot's own depths are probed by
#: ``check_robot_refuses_bad_depth``); and thread counts (a name holding ``threads``),
#: which must not exceed the machine's CPUs.
RUN_RANGE_FIELDS = ("acceleration_m_per_s2", "cutoff_hz", "depth_m")


def _run_fields(spec: PluginSpec) -> Iterator[tuple[str, FieldInfo]]:
    for name, info in spec.config.model_fields.items():
        if "threads" in name or name.endswith(RUN_RANGE_FIELDS[:2]) or (
                spec.kind is Kind.PLANNER and name.endswith("depth_m")):
            yield name, info


def _nan_in(outputs: Any) -> bool:
    if isinstance(outputs, np.ndarray):
        return outputs.dtype.kind == "f" and bool(np.isnan(outputs).any())
    if isinstance(outputs, list | tuple):
        return any(_nan_in(o) for o in outputs)
    if isinstance(outputs, Mapping):
        return any(_nan_in(o) for o in outputs.values())
    probabilities = getattr(outputs, "probabilities", None)
    return probabilities is not None and _nan_in(np.asarray(probabilities, dtype=float))


@check()
def check_run_range_ends(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """The low end of each field a run meets (:data:`RUN_RANGE_FIELDS`: accelerations, filter
    cutoffs, planner depths) is refused by validation or built and driven cleanly (no error,
    no NaN output); a thread count larger than the machine's CPUs is refused. ``validate``
    must see what the run will meet."""
    validator = spec.load_validator() if spec.validator else None
    base = dict(spec.check_config or {})
    problems: list[str] = []
    for name, info in _run_fields(spec):
        if "threads" in name:
            for value in {*range_extremes(info), machine_cpus() + 1}:
                if value > machine_cpus() and _accepted(spec, validator, base, name, value):
                    problems.append(f"{name} = {value!r} is accepted, more threads than the "
                                    f"machine's {machine_cpus()} CPUs")
            continue
        for value in range_extremes(info)[:1]:
            if not _accepted(spec, validator, base, name, value):
                continue
            if name.endswith("depth_m") and value <= 0:
                problems.append(f"{name} = {value!r} is accepted; robots refuse a depth that "
                                "is not positive (bound it with gt=0)")
                continue
            try:
                outputs = _exercise(spec, registry, config=_with(base, name, value))
            except CheckFailure as exc:
                problems.append(f"{name} = {value!r} is accepted but fails when driven: {exc}")
                continue
            except (ValueError, RuntimeError, ArithmeticError) as exc:
                problems.append(f"{name} = {value!r} is accepted by validate but raised "
                                f"{type(exc).__name__} when driven: {exc}")
                continue
            if _nan_in(outputs):
                problems.append(f"{name} = {value!r} is accepted by validate but gives NaN "
                                "when driven")
    if problems:
        raise CheckFailure(
            f"{spec.kind} plugin {spec.name!r}: " + "; ".join(problems) + " — bound the field "
            "in its config model (or refuse the value in its validator) at what the run can do"
        )


def _accepted(spec: PluginSpec, validator: Any, base: Mapping[str, Any], name: str,
              value: Any) -> bool:
    data = _with(base, name, value)
    if validator is None:
        try:
            spec.config.model_validate(data)
        except ValidationError:
            return False
        return True
    return _refused(spec, validator, data, name) is None
