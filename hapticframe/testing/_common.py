"""Checks that apply to every plugin kind: the spec record, config round trip, lazy imports."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from pydantic import ValidationError

from hapticframe._kind import Kind
from hapticframe._registry import Registry
from hapticframe._specs import PluginSpec
from hapticframe.run._components import INTERFACES
from hapticframe.testing._harness import CheckFailure, make_component, release_component
from hapticframe.testing._import_probe import modules_loaded_by

__all__ = ["CHECKS", "HEAVY_MODULES", "check"]

#: Modules that listing, validation and schema generation must never import.
HEAVY_MODULES = ("torch", "sklearn", "serial", "can", "dynamixel_sdk", "matplotlib")

CheckFunction = Callable[..., None]
#: Check functions by kind, in the order they run.
CHECKS: dict[Kind, list[CheckFunction]] = {kind: [] for kind in Kind}


def check(*kinds: Kind) -> Callable[[CheckFunction], CheckFunction]:
    """Register a check function for ``kinds`` (all kinds when none are given)."""

    def register(func: CheckFunction) -> CheckFunction:
        for kind in kinds or tuple(Kind):
            CHECKS[kind].append(func)
        return func

    return register


@check()
def check_spec_record(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """The factory resolves to a component class of the spec's kind."""
    factory = spec.load_factory()
    interface = INTERFACES[spec.kind]
    if isinstance(factory, type) and not issubclass(factory, interface):
        raise CheckFailure(
            f"factory {spec.factory!r} is {factory.__name__}, which does not derive from "
            f"hapticframe.kinds.{interface.__name__}"
        )
    if not callable(factory):
        raise CheckFailure(f"factory {spec.factory!r} is not callable")
    try:
        spec.config.model_validate(spec.check_config or {})
    except ValidationError as exc:
        raise CheckFailure(
            f"check_config does not validate against {spec.config.__name__}: {exc}"
        ) from exc


@check()
def check_config_round_trip(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Config → JSON → config is lossless, the JSON Schema accepts it, unknown keys fail."""
    config = spec.config.model_validate(spec.check_config or {})
    try:
        dumped = config.model_dump(mode="json")
        text = json.dumps(dumped, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise CheckFailure(
            f"config of {spec.name!r} does not serialise to plain JSON: {exc}"
        ) from exc
    again = spec.config.model_validate_json(text)
    if again != config:
        raise CheckFailure(
            f"config of {spec.name!r} changes in a JSON round trip: {config!r} became {again!r}"
        )
    try:
        schema = spec.config.model_json_schema()
    except Exception as exc:
        raise CheckFailure(f"config model of {spec.name!r} has no JSON Schema: {exc}") from exc
    try:
        import jsonschema
    except ImportError:  # pragma: no cover - part of the test extra
        pass  # without jsonschema the kit cannot cross-check the schema; the rest still runs
    else:
        try:
            jsonschema.validate(dumped, schema)
        except jsonschema.ValidationError as exc:
            raise CheckFailure(
                f"the JSON Schema of {spec.name!r} rejects its own config: {exc.message}"
            ) from exc
    try:
        spec.config.model_validate({**dumped, "no_such_key_for_the_kit": 1})
    except ValidationError:
        pass
    else:
        raise CheckFailure(f"config model of {spec.name!r} accepts unknown keys")


def _registration_module(spec: PluginSpec, registry: Registry | None) -> str | None:
    if registry is None:
        return None
    reg = registry.plugins[spec.kind].get(spec.name)
    if reg is None or not reg.source.module:
        return None
    return reg.source.module.partition(":")[0]


@check()
def check_lazy_import(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """Registration and config modules import no heavy or device library.

    Each question is answered as a fresh interpreter would (see ``_import_probe``: a forked
    child of one helper that imported the core once) and cached for the process.
    """
    from hapticframe._manager import get_registry

    modules = [spec.config.__module__]
    registration = _registration_module(spec, registry or get_registry())
    if registration:
        modules.insert(0, registration)
    forbidden = set(HEAVY_MODULES) | set(spec.requires)
    try:
        leaked = sorted(modules_loaded_by(modules, forbidden))
    except ImportError as exc:
        raise CheckFailure(f"importing {', '.join(modules)} failed: {exc}") from exc
    if leaked:
        raise CheckFailure(
            f"importing {', '.join(modules)} also imports {', '.join(leaked)}: move those "
            "imports into the implementation module (the spec's factory) or inside functions"
        )


@check()
def check_builds(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """The factory builds a component of the right kind from the check config."""
    component = make_component(spec, registry=registry, interface=INTERFACES[spec.kind])
    try:
        if component.kind is not spec.kind:
            raise CheckFailure(
                f"{spec.factory!r} built {type(component).__name__}, not a {spec.kind} component"
            )
        repr(component)
    finally:
        release_component(component)


def outputs_equal(a: Any, b: Any) -> bool:
    """Exact equality of nested outputs (NaN == NaN, in arrays and as floats)."""
    import numpy as np

    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(outputs_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(outputs_equal(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a_arr, b_arr = np.asarray(a), np.asarray(b)
        return a_arr.shape == b_arr.shape and bool(np.array_equal(a_arr, b_arr, equal_nan=True))
    if isinstance(a, float) and isinstance(b, float) and a != a and b != b:
        return True  # NaN == NaN, as for arrays
    return bool(a == b)
