"""A boolean is not a number: ``hinge_spacing_m: true`` is refused, not read as 1.0.

Pydantic's lax mode converts ``true`` to 1 and 1.0 for ``int`` and ``float`` fields; strict
mode would also refuse a YAML list for a tuple. So the raw data is walked beside the
experiment model's annotations instead, and every boolean whose field admits numbers but
not booleans is refused at its dotted path, in every section and every plugin's config
(nested models, lists, tuples, optional fields and tagged unions included).
"""

from __future__ import annotations

import types
from collections.abc import Iterator
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel

from hapticframe._config._load import LoadedFile, join_path
from hapticframe._errors import Issue

__all__ = ["bool_issues"]

_UNIONS = (Union, types.UnionType)
_NUMBERS = (int, float)


def _options(annotation: Any) -> list[Any]:
    """The members of a union (Annotated stripped), or the annotation alone."""
    while get_origin(annotation) is Annotated:
        annotation = get_args(annotation)[0]
    if get_origin(annotation) in _UNIONS:
        out: list[Any] = []
        for member in get_args(annotation):
            out.extend(_options(member))
        return out
    return [annotation]


def _admits_bool(options: list[Any]) -> bool:
    for option in options:
        if option is bool or option is Any:
            return True
        if get_origin(option) is Literal and any(isinstance(v, bool) for v in get_args(option)):
            return True
    return False


def _is_number(options: list[Any]) -> bool:
    return any(option in _NUMBERS for option in options)


def _pick_model(options: list[Any], raw: dict[str, Any]) -> type[BaseModel] | None:
    """The model of ``options`` that ``raw`` is: by its tag (``type``, ``shape``,
    ``kind``) among tagged variants, else the only model."""
    models = [o for o in options if isinstance(o, type) and issubclass(o, BaseModel)]
    if len(models) == 1:
        return models[0]
    for model in models:
        for tag in ("type", "shape"):
            field = model.model_fields.get(tag)
            if field is not None and get_origin(field.annotation) is Literal and (
                raw.get(tag) in get_args(field.annotation)
            ):
                return model
    return None


def _walk(annotation: Any, raw: Any, path: str) -> Iterator[str]:
    """Dotted paths of the booleans in ``raw`` where ``annotation`` wants a number."""
    options = _options(annotation)
    if isinstance(raw, bool):
        if _is_number(options) and not _admits_bool(options):
            yield path
        return
    if isinstance(raw, dict):
        model = _pick_model(options, raw)
        if model is not None:
            for key, value in raw.items():
                field = model.model_fields.get(key)
                if field is not None:
                    yield from _walk(field.annotation, value, join_path(path, key))
            return
        for option in options:
            if get_origin(option) is dict and len(get_args(option)) == 2:
                for key, value in raw.items():
                    yield from _walk(get_args(option)[1], value, join_path(path, str(key)))
                return
        return
    if isinstance(raw, list):
        for option in options:
            origin, args = get_origin(option), get_args(option)
            if origin is list and args:
                items = [args[0]] * len(raw)
            elif origin is tuple and len(args) == 2 and args[1] is Ellipsis:
                items = [args[0]] * len(raw)
            elif origin is tuple and args:
                items = list(args[: len(raw)])
            else:
                continue
            for index, (item, value) in enumerate(zip(items, raw, strict=False)):
                yield from _walk(item, value, join_path(path, index))
            return


def bool_issues(model: type[BaseModel], loaded: LoadedFile) -> list[Issue]:
    """A located issue for every ``true``/``false`` written where a number belongs."""
    issues = []
    for path in _walk(model, loaded.data, ""):
        value = _value_at(loaded.data, path)
        issues.append(Issue(
            path, f"must be a number, not the boolean {str(value).lower()} (booleans are not "
            "read as 1 and 0)", loaded.line_of(path),
        ))
    return issues


def _value_at(data: Any, path: str) -> Any:
    value = data
    for part in path.replace("[", ".[").split("."):
        if not part:
            continue
        if part.startswith("["):
            value = value[int(part[1:-1])]
        else:
            value = value[part]
    return value
