"""Foxglove's well-known JSON schemas for ``run.mcap``, and the messages that follow them.

Foxglove and Lichtblick draw a channel in their 3D panel when its schema is named after
one of Foxglove's message schemas (``foxglove.Grid``, ``foxglove.SceneUpdate``,
``foxglove.PoseInFrame``) and its JSON messages follow that schema. The schemas below are
Foxglove's own (github.com/foxglove/foxglove-sdk, ``schemas/jsonschema``), with the scene
entity cut down to the primitives a run writes (lines and texts); every field keeps
Foxglove's name, type and meaning. Everything lies in the frame ``map``: the search plane
is z = 0, depth into the sand is negative z.

Enumerations are written as their integer values (``NumericType.FLOAT32`` = 7,
``LineType.LINE_STRIP`` = 0), as Foxglove's JSON encoding takes them.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "FRAME",
    "GRID",
    "POSE_IN_FRAME",
    "SCENE_UPDATE",
    "SCHEMAS",
    "decode_grid",
    "grid_message",
    "line_entity",
    "pose_message",
    "scene_update",
    "stamp",
]

#: The frame every map, pose and scene entity of a run lies in.
FRAME = "map"
GRID = "foxglove.Grid"
SCENE_UPDATE = "foxglove.SceneUpdate"
POSE_IN_FRAME = "foxglove.PoseInFrame"

#: Foxglove's NumericType.FLOAT32.
FLOAT32 = 7
#: Foxglove's LineType values.
LINE_STRIP, LINE_LOOP = 0, 1


def _object(title: str, properties: Mapping[str, Any], required: Sequence[str] = (),
            description: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {"title": title, "type": "object", "properties": dict(properties)}
    if description:
        out["description"] = description
    if required:
        out["required"] = list(required)
    return out


_NUMBER = {"type": "number"}
_TIME = {"type": "object", "title": "time", "properties": {
    "sec": {"type": "integer", "minimum": 0},
    "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}}
_DURATION = {"type": "object", "title": "duration", "properties": {
    "sec": {"type": "integer"}, "nsec": {"type": "integer", "minimum": 0,
                                         "maximum": 999_999_999}}}
_VECTOR3 = _object("foxglove.Vector3", {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER},
                   ("x", "y", "z"))
_QUATERNION = _object("foxglove.Quaternion",
                      {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER, "w": _NUMBER},
                      ("x", "y", "z", "w"))
_POSE = _object("foxglove.Pose", {"position": _VECTOR3, "orientation": _QUATERNION},
                ("position", "orientation"))
_COLOR = _object("foxglove.Color", {"r": _NUMBER, "g": _NUMBER, "b": _NUMBER, "a": _NUMBER},
                 ("r", "g", "b", "a"))
_POINT3 = _object("foxglove.Point3", {"x": _NUMBER, "y": _NUMBER, "z": _NUMBER},
                  ("x", "y", "z"))
_LINE = _object("foxglove.LinePrimitive", {
    "type": {"title": "foxglove.LineType", "oneOf": [
        {"title": "LINE_STRIP", "const": 0}, {"title": "LINE_LOOP", "const": 1},
        {"title": "LINE_LIST", "const": 2}]},
    "pose": _POSE, "thickness": _NUMBER, "scale_invariant": {"type": "boolean"},
    "points": {"type": "array", "items": _POINT3}, "color": _COLOR,
    "colors": {"type": "array", "items": _COLOR},
    "indices": {"type": "array", "items": {"type": "integer", "minimum": 0}},
}, ("type", "pose", "thickness", "scale_invariant", "points", "color", "colors", "indices"))
_TEXT = _object("foxglove.TextPrimitive", {
    "pose": _POSE, "billboard": {"type": "boolean"}, "font_size": _NUMBER,
    "scale_invariant": {"type": "boolean"}, "color": _COLOR, "text": {"type": "string"},
}, ("pose", "billboard", "font_size", "scale_invariant", "color", "text"))
#: The scene entity's primitive lists that a run leaves empty.
_UNUSED_PRIMITIVES = ("arrows", "cubes", "spheres", "cylinders", "triangles", "models")
_ENTITY = _object("foxglove.SceneEntity", {
    "timestamp": _TIME, "frame_id": {"type": "string"}, "id": {"type": "string"},
    "lifetime": _DURATION, "frame_locked": {"type": "boolean"},
    "metadata": {"type": "array", "items": _object(
        "foxglove.KeyValuePair", {"key": {"type": "string"}, "value": {"type": "string"}},
        ("key", "value"))},
    "lines": {"type": "array", "items": _LINE},
    "texts": {"type": "array", "items": _TEXT},
    # Primitives a run never writes: present and empty, as Foxglove's schema requires.
    **{kind: {"type": "array", "maxItems": 0} for kind in _UNUSED_PRIMITIVES},
}, ("timestamp", "frame_id", "id", "lifetime", "frame_locked", "metadata", "lines", "texts",
    *_UNUSED_PRIMITIVES),
    "A visual element in a 3D scene (the primitives a run writes: lines, texts)")
_DELETION = _object("foxglove.SceneEntityDeletion", {
    "timestamp": _TIME,
    "type": {"title": "foxglove.SceneEntityDeletionType", "oneOf": [
        {"title": "MATCHING_ID", "const": 0}, {"title": "ALL", "const": 1}]},
    "id": {"type": "string"}}, ("timestamp", "type", "id"))

_DRAFT = "https://json-schema.org/draft/2020-12/schema"

#: Foxglove's JSON schemas the recording registers, by name.
SCHEMAS: dict[str, dict[str, Any]] = {
    GRID: {"$schema": _DRAFT, **_object(GRID, {
        "timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE,
        "column_count": {"type": "integer", "minimum": 0},
        "cell_size": _object("foxglove.Vector2", {"x": _NUMBER, "y": _NUMBER}),
        "row_stride": {"type": "integer", "minimum": 0},
        "cell_stride": {"type": "integer", "minimum": 0},
        "fields": {"type": "array", "items": _object("foxglove.PackedElementField", {
            "name": {"type": "string"}, "offset": {"type": "integer", "minimum": 0},
            "type": {"title": "foxglove.NumericType", "oneOf": [
                {"title": t, "const": i} for i, t in enumerate(
                    ("UNKNOWN", "UINT8", "INT8", "UINT16", "INT16", "UINT32", "INT32",
                     "FLOAT32", "FLOAT64"))]}})},
        "data": {"type": "string", "contentEncoding": "base64"},
    }, description="A 2D grid of data")},
    SCENE_UPDATE: {"$schema": _DRAFT, **_object(SCENE_UPDATE, {
        "deletions": {"type": "array", "items": _DELETION},
        "entities": {"type": "array", "items": _ENTITY},
    }, description="An update to the entities displayed in a 3D scene")},
    POSE_IN_FRAME: {"$schema": _DRAFT, **_object(POSE_IN_FRAME, {
        "timestamp": _TIME, "frame_id": {"type": "string"}, "pose": _POSE,
    }, description="A timestamped pose for an object or reference frame in 3D space")},
}


def stamp(t_s: float) -> dict[str, int]:
    """Foxglove's ``time`` of ``t_s`` seconds (model time; negative times clip to 0)."""
    ns = max(round(float(t_s) * 1e9), 0)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0, yaw_rad: float = 0.0
          ) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw_rad / 2),
                            "w": math.cos(yaw_rad / 2)}}


def grid_message(t_s: float, origin_m: Sequence[float], cell_size_m: Sequence[float],
                 mean: ArrayLike, std: ArrayLike) -> dict[str, Any]:
    """A ``foxglove.Grid`` of a map's occupancy ``mean`` and ``std`` (``(rows, columns)``,
    row 0 at the lowest y, column 0 at the lowest x), its lower-left corner at
    ``origin_m``; cells hold two little-endian float32 fields, ``mean`` and ``std``."""
    m = np.asarray(mean, dtype=np.float64)
    s = np.asarray(std, dtype=np.float64)
    if m.ndim != 2 or m.shape != s.shape:
        raise ValueError(f"mean {m.shape} and std {s.shape} must be equal 2-D grids")
    rows, columns = m.shape
    cells = np.empty((rows, columns, 2), dtype="<f4")
    cells[..., 0] = m
    cells[..., 1] = s
    return {
        "timestamp": stamp(t_s), "frame_id": FRAME,
        "pose": _pose(float(origin_m[0]), float(origin_m[1])),
        "column_count": int(columns),
        "cell_size": {"x": float(cell_size_m[0]), "y": float(cell_size_m[1])},
        "row_stride": int(columns) * 8, "cell_stride": 8,
        "fields": [{"name": "mean", "offset": 0, "type": FLOAT32},
                   {"name": "std", "offset": 4, "type": FLOAT32}],
        "data": base64.b64encode(cells.tobytes()).decode("ascii"),
    }


def decode_grid(message: Mapping[str, Any]) -> dict[str, NDArray[np.float64]]:
    """The fields of a ``foxglove.Grid`` of :func:`grid_message` as ``(rows, columns)``
    float64 arrays, plus ``xs`` and ``ys``: the cell centres (metres)."""
    columns = int(message["column_count"])
    raw = base64.b64decode(message["data"])
    stride = int(message["cell_stride"])
    if columns <= 0 or stride <= 0 or int(message["row_stride"]) != columns * stride:
        raise ValueError("a grid with padded rows or no columns is not one a run writes")
    cells = np.frombuffer(raw, dtype=np.uint8).reshape(-1, columns, stride)
    out: dict[str, NDArray[np.float64]] = {}
    for field in message["fields"]:
        if int(field["type"]) != FLOAT32:
            raise ValueError(f"grid field {field['name']!r} is not float32")
        offset = int(field["offset"])
        out[str(field["name"])] = np.ascontiguousarray(
            cells[..., offset:offset + 4]).view("<f4")[..., 0].astype(np.float64)
    rows = cells.shape[0]
    position = message["pose"]["position"]
    dx, dy = float(message["cell_size"]["x"]), float(message["cell_size"]["y"])
    out["xs"] = (float(position["x"]) + (np.arange(columns) + 0.5) * dx).astype(np.float64)
    out["ys"] = (float(position["y"]) + (np.arange(rows) + 0.5) * dy).astype(np.float64)
    return out


def pose_message(t_s: float, position_m: Sequence[float], heading_rad: float,
                 depth_m: float) -> dict[str, Any]:
    """A ``foxglove.PoseInFrame`` of the fingertip: x, y, heading about z, and depth into
    the sand as negative z (0 when the depth is unknown)."""
    z = -float(depth_m) if math.isfinite(depth_m) else 0.0
    heading = float(heading_rad) if math.isfinite(heading_rad) else 0.0
    x, y = (float(v) if math.isfinite(v) else 0.0 for v in position_m[:2])
    return {"timestamp": stamp(t_s), "frame_id": FRAME, "pose": _pose(x, y, z, heading)}


def line_entity(entity_id: str, t_s: float, points_m: ArrayLike,
                colour: Sequence[float], *, closed: bool = True, thickness_m: float = 0.003,
                metadata: Mapping[str, str] | None = None) -> dict[str, Any]:
    """A scene entity holding one line through ``points_m`` (``(n, 2)``, at z = 0)."""
    p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    r, g, b, a = (float(c) for c in colour)
    return {
        "timestamp": stamp(t_s), "frame_id": FRAME, "id": entity_id,
        "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
        "metadata": [{"key": k, "value": v} for k, v in (metadata or {}).items()],
        "lines": [{
            "type": LINE_LOOP if closed else LINE_STRIP, "pose": _pose(),
            "thickness": thickness_m, "scale_invariant": False,
            "points": [{"x": x, "y": y, "z": 0.0} for x, y in p.tolist()],
            "color": {"r": r, "g": g, "b": b, "a": a}, "colors": [], "indices": [],
        }],
        "texts": [],
        **{kind: [] for kind in _UNUSED_PRIMITIVES},
    }


def scene_update(entities: Iterable[Mapping[str, Any]],
                 deletions: Iterable[str] = (), t_s: float = 0.0) -> dict[str, Any]:
    """A ``foxglove.SceneUpdate``: ``entities`` added or replaced (by id), ``deletions``
    (ids) removed first."""
    return {"deletions": [{"timestamp": stamp(t_s), "type": 0, "id": d} for d in deletions],
            "entities": [dict(e) for e in entities]}
