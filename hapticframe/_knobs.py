"""Declared speed/accuracy knobs (issue 18): what ``hapticframe sweep --declared`` varies.

A plugin declares its knobs on its spec (:class:`hapticframe.Knob`); the run loop's own
knobs (``run.lookahead_steps``, ``run.map_update_every_steps``) are declared here. This
module finds the knobs of an experiment and checks a knob against a config model (the
conformance kit's ``check_knobs`` reports what :func:`knob_problems` finds). Import-light:
pydantic and the standard library only.
"""

from __future__ import annotations

import copy
import difflib
import math
from collections.abc import Iterable, Mapping
from types import UnionType
from typing import TYPE_CHECKING, Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo

from hapticframe._specs import Knob

if TYPE_CHECKING:
    from hapticframe._config import Experiment

__all__ = [
    "RUN_KNOBS",
    "RUN_KNOB_ID",
    "declared_knobs",
    "describe_values",
    "knob_duplicates",
    "knob_problems",
    "knob_record",
    "resolve_field",
]

#: The id :func:`declared_knobs` gives the run settings' knobs (``--set run.FIELD=VALUE``).
RUN_KNOB_ID = "run"

#: The run loop's own knobs, fields of the experiment's ``run:`` section.
RUN_KNOBS: tuple[Knob, ...] = (
    Knob(
        "lookahead_steps",
        "larger batches: fewer classifier calls per step; results unchanged (rewound and "
        "replayed at an interaction)",
        values=(1, 16, 64, 256),
    ),
    Knob(
        "map_update_every_steps",
        "map updates during a movement (0: once per movement): fresher map for the planner "
        "and force halts against more map fits",
        values=(0, 100, 25, 10),
    ),
)


def declared_knobs(experiment: Experiment, *, run: bool = True) -> list[tuple[str, Knob]]:
    """The knobs an experiment's components declare, as ``(component id, knob)`` pairs.

    Parameters
    ----------
    experiment : Experiment
        A validated experiment (:func:`hapticframe.validate_file`).
    run : bool
        Also list the run loop's knobs (:data:`RUN_KNOBS`) under the id ``"run"``, the
        override path of the ``run:`` section. Only those the experiment can use: the
        look-ahead needs a robot, map updates during a movement need a map.

    Returns
    -------
    list of (str, Knob)
        In the experiment's build order, each component's knobs in declaration order; the
        override path of a pair is ``f"{id}.{knob.field}"``.
    """
    from hapticframe._kind import Kind

    pairs = [
        (entry.id, knob) for entry in experiment.components for knob in entry.registered.spec.knobs
    ]
    if run:
        has_robot = bool(experiment.of_kind(Kind.ROBOT))
        has_map = bool(experiment.of_kind(Kind.MAP))
        for knob in RUN_KNOBS:
            if (knob.field == "lookahead_steps" and not has_robot) or (
                knob.field == "map_update_every_steps" and not (has_robot and has_map)
            ):
                continue
            pairs.append((RUN_KNOB_ID, knob))
    return pairs


def _model_classes(annotation: Any) -> list[type[BaseModel]]:
    """The pydantic models an annotation may hold (through Optional, unions, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    origin = get_origin(annotation)
    if origin is Annotated:
        return _model_classes(get_args(annotation)[0])
    if origin is Union or origin is UnionType:
        return [m for arg in get_args(annotation) for m in _model_classes(arg)]
    return []


def resolve_field(model: type[BaseModel], path: str) -> FieldInfo:
    """The field a dotted path names inside ``model``, nested models included.

    Raises
    ------
    KeyError
        With a message naming the missing part and the close field names.
    """
    models = [model]
    parts = path.split(".")
    for depth, part in enumerate(parts):
        infos = [m.model_fields[part] for m in models if part in m.model_fields]
        if not infos:
            where = ".".join(parts[:depth]) or model.__name__
            names = sorted({name for m in models for name in m.model_fields})
            close = difflib.get_close_matches(part, names, n=3, cutoff=0.6)
            hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
            raise KeyError(f"{where} has no field {part!r}{hint}")
        if depth == len(parts) - 1:
            return infos[0]
        models = [m for info in infos for m in _model_classes(info.annotation)]
        if not models:
            raise KeyError(f"{'.'.join(parts[: depth + 1])} is not a nested model")
    raise AssertionError("unreachable: a field path has at least one part")


def _bounds(info: FieldInfo) -> list[tuple[str, float]]:
    """The field's numeric bounds as ``(operator, limit)`` pairs."""
    found = []
    for item in info.metadata:
        for op in ("gt", "ge", "lt", "le"):
            limit = getattr(item, op, None)
            if isinstance(limit, (int, float)):
                found.append((op, float(limit)))
    return found


_HOLDS = {
    "gt": lambda x, b: x > b,
    "ge": lambda x, b: x >= b,
    "lt": lambda x, b: x < b,
    "le": lambda x, b: x <= b,
}
_SYMBOL = {"gt": ">", "ge": "≥", "lt": "<", "le": "≤"}


def _with_value(model: type[BaseModel], base: Mapping[str, Any], path: str, value: Any
                ) -> dict[str, Any]:
    """``base`` with ``path`` set to ``value``; a nested model the base leaves out (or sets
    to None) is filled in from the validated base, so that only the knob's field changes."""
    data = copy.deepcopy(dict(base))
    full: Any = model.model_validate(base).model_dump(mode="json")
    node = data
    parts = path.split(".")
    for part in parts[:-1]:
        full = full.get(part) if isinstance(full, dict) else None
        if not isinstance(node.get(part), dict):
            node[part] = copy.deepcopy(full) if isinstance(full, dict) else {}
        node = node[part]
    node[parts[-1]] = value
    return data


def _get(config: BaseModel, path: str) -> Any:
    value: Any = config
    for part in path.split("."):
        value = getattr(value, part)
    return value


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, (int, float)) and not isinstance(b, bool):
        return math.isclose(a, float(b), rel_tol=1e-12, abs_tol=0.0)
    return bool(a == b)


def _first_error(exc: ValidationError) -> str:
    error = exc.errors()[0]
    where = ".".join(str(p) for p in error.get("loc", ()))
    return f"{where}: {error['msg']}" if where else str(error["msg"])


def knob_problems(
    model: type[BaseModel],
    knob: Knob,
    bases: Iterable[Mapping[str, Any]] = ({},),
) -> list[str]:
    """What is wrong with ``knob`` as a knob of ``model``; empty when nothing is.

    The knob's field must exist (nested models included); a range must lie inside the
    field's bounds; every value of :meth:`Knob.sweep_values` (and a range's ends) must
    validate when set on each config in ``bases`` and reach the field unchanged; and the
    knob must offer at least two distinct values.
    """
    try:
        info = resolve_field(model, knob.field)
    except KeyError as exc:
        return [f"knob {knob.field!r}: {exc.args[0]}"]
    problems = []
    if knob.low is not None and knob.high is not None:
        for end, x in (("low", float(knob.low)), ("high", float(knob.high))):
            for op, limit in _bounds(info):
                if not _HOLDS[op](x, limit):
                    problems.append(
                        f"knob {knob.field!r}: range {end} {x:g} is outside the field's bounds "
                        f"(must be {_SYMBOL[op]} {limit:g})"
                    )
    values = list(knob.sweep_values())
    if len({repr(v) for v in values}) < 2:
        problems.append(f"knob {knob.field!r}: sweeps {len(values)} distinct value(s); a knob "
                        "needs at least two")
    if knob.low is not None and knob.high is not None and not knob.integer:
        values += [v for v in (knob.low, knob.high) if v not in values]
    for base in bases:
        for value in values:
            try:
                config = model.model_validate(_with_value(model, base, knob.field, value))
            except ValidationError as exc:
                problems.append(f"knob {knob.field!r}: value {value!r} does not validate "
                                f"({_first_error(exc)})")
                continue
            got = _get(config, knob.field)
            if not _same(got, value):
                problems.append(f"knob {knob.field!r}: value {value!r} becomes {got!r} in the "
                                "config; declare values of the field's type")
    return list(dict.fromkeys(problems))


def knob_duplicates(knobs: Iterable[Knob]) -> list[str]:
    """Fields declared by more than one knob."""
    seen: set[str] = set()
    repeated = []
    for knob in knobs:
        if knob.field in seen and knob.field not in repeated:
            repeated.append(knob.field)
        seen.add(knob.field)
    return repeated


def describe_values(knob: Knob) -> str:
    """The knob's values for a listing: ``0.025, 0.05, 0.1`` or ``log 0.01..0.1 (5)``."""
    if knob.values:
        return ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in knob.values)
    assert knob.low is not None and knob.high is not None
    kind = " integers" if knob.integer else ""
    return f"{knob.scale} {knob.low:g}..{knob.high:g} ({knob.points}{kind})"


def knob_record(knob: Knob) -> dict[str, Any]:
    """A knob as JSON-ready data (``hapticframe plugins --json``), its sweep values included."""
    record: dict[str, Any] = {"field": knob.field, "trades": knob.trades,
                              "values": list(knob.sweep_values())}
    if knob.low is not None:
        record.update(low=knob.low, high=knob.high, scale=knob.scale, points=knob.points,
                      integer=knob.integer)
    return record
