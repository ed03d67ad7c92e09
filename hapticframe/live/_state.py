"""What the live page shows, folded from a run's recording messages.

The run's thread only appends to a :class:`MessageQueue` (bounded; when full, the oldest
message goes: the loop never waits for the page). The server's thread drains it into a
:class:`LiveState`, which keeps the latest picture (maps, paths, force and class
probabilities over the last seconds, movements, phase, metrics so far) and renders it as
one JSON frame for the page. :class:`RecordingTimeline` gives the same frames for a
finished or recovered recording at any time (``hapticframe view``'s slider).
"""

from __future__ import annotations

import base64
import math
import time
from collections import deque
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe._defaults import OUTLINE_LEVEL
from hapticframe.run._channels import (
    CLASSIFIER,
    MAP_GRID,
    METRICS,
    MOVEMENT,
    ROBOT_STATE,
    SAFETY_HALT,
    SCENE,
    SENSOR,
)

__all__ = [
    "END_TOPIC",
    "LiveState",
    "MessageQueue",
    "RecordingTimeline",
    "decode_grid",
]

#: The topic :meth:`LiveState.end` is told the run's end on (never written to a file).
END_TOPIC = "/hapticframe/live/end"
#: Model-time seconds of force and class probability the page plots.
WINDOW_S = 10.0
#: At most this many points of a time series or a path go into one frame.
MAX_SERIES_POINTS = 600
MAX_PATH_POINTS = 4000
#: A path point is kept when the fingertip has moved at least this far (m) since the last.
PATH_STEP_M = 2e-3
#: The std colour scale's top when a map's std is 0 everywhere (a Bernoulli's std is at
#: most 0.5); otherwise the scale runs to the map's largest std, as the report's figure.
STD_SCALE = 0.5

Message = tuple[str, float, Mapping[str, Any]]


class MessageQueue:
    """A bounded queue of recording messages that drops the oldest when full.

    :meth:`put` is a recording listener (``fn(topic, t_s, data)``): one ``deque.append``,
    atomic under the GIL and never blocking, so the run's thread pays next to nothing.
    """

    def __init__(self, maxlen: int = 20000) -> None:
        self._items: deque[Message] = deque(maxlen=maxlen)
        self.put_count = 0
        self.taken = 0

    def put(self, topic: str, t_s: float, data: Mapping[str, Any]) -> None:
        self._items.append((topic, t_s, data))
        self.put_count += 1

    def drain(self) -> list[Message]:
        """Every message waiting, oldest first."""
        out: list[Message] = []
        items = self._items
        while True:
            try:
                out.append(items.popleft())
            except IndexError:
                break
        self.taken += len(out)
        return out

    @property
    def dropped(self) -> int:
        """Messages that were pushed out unread (the page fell behind)."""
        return max(self.put_count - self.taken - len(self._items), 0)


def decode_grid(data: Mapping[str, Any]) -> dict[str, Any]:
    """A ``foxglove.Grid`` message's ``mean`` and ``std`` fields as ``(rows, columns)`` float64
    arrays, with the grid's origin (lower-left corner, m) and cell size (m).

    Raises
    ------
    ValueError
        When the message lacks a ``mean`` field or its sizes do not add up.
    """
    raw = base64.b64decode(data["data"])
    columns = int(data["column_count"])
    cell_stride = int(data["cell_stride"])
    row_stride = int(data["row_stride"])
    if columns <= 0 or row_stride < columns * cell_stride or len(raw) % row_stride:
        raise ValueError(f"grid sizes do not add up: {columns} columns, cell_stride "
                         f"{cell_stride}, row_stride {row_stride}, {len(raw)} bytes")
    rows = len(raw) // row_stride
    buffer = np.frombuffer(raw, dtype=np.uint8).reshape(rows, row_stride)
    fields: dict[str, NDArray[np.float64]] = {}
    for spec in data.get("fields", []):
        offset = int(spec["offset"])
        cells = buffer[:, : columns * cell_stride].reshape(rows, columns, cell_stride)
        chunk = np.ascontiguousarray(cells[:, :, offset:offset + 4])
        fields[str(spec["name"])] = chunk.view("<f4")[:, :, 0].astype(np.float64)
    if "mean" not in fields:
        raise ValueError(f"the grid has no 'mean' field (fields: {sorted(fields)})")
    position = data.get("pose", {}).get("position", {})
    size = data.get("cell_size", {})
    return {"mean": fields["mean"], "std": fields.get("std"),
            "origin_m": [float(position.get("x", 0.0)), float(position.get("y", 0.0))],
            "cell_m": [float(size.get("x", 1.0)), float(size.get("y", 1.0))]}


def _bytes(values: NDArray[np.float64], scale: float) -> str:
    """Cells as base64 bytes 0..255 (``values / scale``; NaN as 0), the page's image."""
    clean = np.nan_to_num(values / scale, nan=0.0)
    return base64.b64encode(np.clip(np.rint(clean * 255), 0, 255).astype(np.uint8)
                            .tobytes()).decode("ascii")


def std_scale(std: NDArray[np.float64]) -> float:
    """The std image's colour scale top: the largest finite std, as matplotlib scales the
    report's std figure (``vmin=0``, ``vmax`` the data's), or :data:`STD_SCALE` when the std
    is 0 (or not finite) everywhere."""
    finite = std[np.isfinite(std)]
    top = float(finite.max()) if finite.size else 0.0
    return top if top > 0.0 else STD_SCALE


def _thin(n: int, most: int) -> slice:
    return slice(None, None, max(1, math.ceil(n / most)))


def _rounded(values: NDArray[np.float64], digits: int = 4) -> list[Any]:
    out: list[Any] = np.round(np.nan_to_num(values, nan=0.0), digits).tolist()
    return out


def _level(estimate: Mapping[str, Any] | None) -> float:
    """The estimated outline's level: the recording's when it says, else the default."""
    try:
        return float(estimate["metadata"]["level"]) if estimate else OUTLINE_LEVEL
    except (KeyError, TypeError, ValueError):
        return OUTLINE_LEVEL


@dataclass
class _Map:
    grid: dict[str, Any]
    t_s: float
    version: int
    frame: dict[str, Any] | None = None
    #: The scene's estimated outline of this map when the frame was made (its cache key).
    estimate: Any = None


@dataclass
class _Series:
    """A time series kept for the last :data:`WINDOW_S` seconds (blocks of arrays)."""

    times: deque[NDArray[np.float64]] = field(default_factory=deque)
    values: deque[NDArray[np.float64]] = field(default_factory=deque)
    count: int = 0

    def add(self, times: NDArray[np.float64], values: NDArray[np.float64]) -> None:
        if not len(times):
            return
        self.times.append(times)
        self.values.append(values)
        self.count += len(times)
        while len(self.times) > 1 and self.times[0][-1] < times[-1] - WINDOW_S:
            self.times.popleft()
            self.values.popleft()

    def window(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        t = np.concatenate(list(self.times))
        v = np.concatenate(list(self.values))
        keep = t >= t[-1] - WINDOW_S
        t, v = t[keep], v[keep]
        step = _thin(len(t), MAX_SERIES_POINTS)
        return t[step], v[step]


@dataclass
class _Path:
    points: list[tuple[float, float]] = field(default_factory=list)
    movements: list[int] = field(default_factory=list)
    last: tuple[float, float] | None = None
    movement: int = 0
    depth_m: float = math.nan


class LiveState:
    """The latest picture of a run, folded from its recording's messages.

    Not thread-safe: one thread folds and renders (the server's).
    """

    def __init__(self, clock: Any = time.monotonic) -> None:
        self._clock = clock
        self._started = clock()
        self.version = 0
        self.t_s = 0.0
        self.status = "running"
        self.maps: dict[str, _Map] = {}
        self.paths: dict[str, _Path] = {}
        self.forces: dict[str, _Series] = {}
        self.probabilities: dict[str, _Series] = {}
        self.classes: dict[str, list[str]] = {}
        self.units: dict[str, dict[str, str]] = {}
        self.movements: list[dict[str, Any]] = []
        self.halts: list[str] = []
        self.metrics: dict[str, Any] = {}
        self.samples: dict[str, int] = {}
        self.max_force_n = 0.0
        self.messages = 0
        self.dropped = 0
        self.errors: dict[str, str] = {}
        #: Why the run stopped when it did not finish (the page shows it with the status).
        self.reason = ""
        #: The map the page shows first (the evaluated one; the person may pick another).
        self.preferred_map: str | None = None
        #: ``/scene`` entities by id: the region, the true objects, the estimated outlines.
        self.scene: dict[str, dict[str, Any]] = {}
        #: Maps whose estimated outline the recording writes on ``/scene`` (or deletes).
        self._estimated: set[str] = set()
        self._frame: dict[str, Any] | None = None
        self._frame_version = -1

    # --- folding -----------------------------------------------------------------------------

    def fold_all(self, messages: Iterable[Message]) -> None:
        for topic, t_s, data in messages:
            self.fold(topic, t_s, data)

    def fold(self, topic: str, t_s: float, data: Mapping[str, Any]) -> None:
        """Take one recording message into the picture (unknown topics are ignored; a
        malformed message is noted in the frame's ``errors``, never raised)."""
        self.messages += 1
        self.version += 1
        if topic != END_TOPIC:
            self.t_s = max(self.t_s, float(t_s))
        try:
            if topic == END_TOPIC:
                self.status = str(data.get("status", "ended"))
                self.reason = str(data.get("reason") or "")
                self._metrics(data.get("metrics"))
            elif topic == SCENE.name:
                self._scene(data)
            elif (map_id := MAP_GRID.id_of(topic)) is not None:
                self._grid(map_id, t_s, data)
            elif (robot_id := ROBOT_STATE.id_of(topic)) is not None:
                self._robot(robot_id, data)
            elif (sensor_id := SENSOR.id_of(topic)) is not None:
                self._sensor(sensor_id, data)
            elif (classifier_id := CLASSIFIER.id_of(topic)) is not None:
                self._classifier(classifier_id, data)
            elif topic == MOVEMENT.name:
                self.movements.append(dict(data))
            elif topic == SAFETY_HALT.name:
                self.halts.append(str(data.get("reason", "")))
            elif topic == METRICS.name:
                self._metrics(data.get("metrics"))
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            self.errors[topic] = f"{type(exc).__name__}: {exc}"

    def end(self, status: str, metrics: Mapping[str, Any] | None = None,
            reason: str = "") -> None:
        """The run has ended (``ok``, ``failed``, ``interrupted``); ``metrics``: its final
        ones; ``reason``: why it stopped, when it did not finish."""
        self.fold(END_TOPIC, self.t_s, {"status": status, "metrics": metrics,
                                        "reason": reason})

    def _metrics(self, metrics: Any) -> None:
        if isinstance(metrics, Mapping):
            self.metrics = {k: v for k, v in metrics.items()
                            if isinstance(v, (int, float, str, bool)) or v is None}
            evaluated = self.metrics.get("evaluated_map")
            if isinstance(evaluated, str):
                self.preferred_map = evaluated

    def _scene(self, data: Mapping[str, Any]) -> None:
        """A ``foxglove.SceneUpdate``: deletions first, then entities added or replaced."""
        for deletion in data.get("deletions", []):
            if int(deletion.get("type", 0)) == 1:  # ALL
                self.scene.clear()
            else:
                self.scene.pop(self._entity_id(deletion["id"]), None)
        for entity in data.get("entities", []):
            lines = [[[float(p["x"]), float(p["y"])] for p in line["points"]]
                     for line in entity.get("lines", [])]
            metadata = {str(kv["key"]): str(kv["value"]) for kv in entity.get("metadata", [])}
            self.scene[self._entity_id(entity["id"])] = {"lines": lines, "metadata": metadata}

    def _entity_id(self, raw: Any) -> str:
        entity_id = str(raw)
        if entity_id.startswith("estimate/"):
            self._estimated.add(entity_id.removeprefix("estimate/"))
        return entity_id

    def _grid(self, map_id: str, t_s: float, data: Mapping[str, Any]) -> None:
        grid = decode_grid(data)
        previous = self.maps.get(map_id)
        self.maps[map_id] = _Map(grid, float(t_s), 1 if previous is None else previous.version + 1)

    def _robot(self, robot_id: str, data: Mapping[str, Any]) -> None:
        path = self.paths.setdefault(robot_id, _Path())
        positions = np.asarray(data["positions_m"], dtype=np.float64).reshape(-1, 2)
        movement = np.asarray(data["movement_index"], dtype=np.float64).reshape(-1)
        depths = np.asarray(data.get("depths_m", []), dtype=np.float64).reshape(-1)
        for (x, y), index in zip(positions.tolist(), movement.tolist(), strict=True):
            last = path.last
            if (last is None or index != path.movement
                    or math.hypot(x - last[0], y - last[1]) >= PATH_STEP_M):
                path.points.append((x, y))
                path.movements.append(int(index))
                path.last = (x, y)
            path.movement = int(index)
        if len(positions):
            end = (float(positions[-1, 0]), float(positions[-1, 1]))
            if path.points[-1] != end:  # the fingertip's latest position is always drawn
                path.points.append(end)
                path.movements.append(path.movement)
                path.last = end
        if len(depths):
            path.depth_m = float(depths[-1])

    def _sensor(self, sensor_id: str, data: Mapping[str, Any]) -> None:
        units = data.get("units")
        if isinstance(units, Mapping):
            self.units[sensor_id] = {str(k): str(v) for k, v in units.items()}
        times = np.asarray(data["timestamps_s"], dtype=np.float64).reshape(-1)
        self.samples[sensor_id] = self.samples.get(sensor_id, 0) + len(times)
        for name, unit in self.units.get(sensor_id, {}).items():
            if unit != "N" or name not in data.get("channels", {}):
                continue
            values = np.asarray(data["channels"][name], dtype=np.float64)
            magnitude = (np.abs(values.reshape(len(times))) if values.ndim == 1
                         else np.linalg.norm(values.reshape(len(times), -1), axis=1))
            if len(magnitude) and np.isfinite(magnitude).any():
                self.max_force_n = max(self.max_force_n, float(np.nanmax(magnitude)))
            self.forces.setdefault(f"{sensor_id}.{name}", _Series()).add(times, magnitude)

    def _classifier(self, cid: str, data: Mapping[str, Any]) -> None:
        classes = [str(c) for c in data["classes"]]
        if self.classes.get(cid, classes) != classes:
            self.probabilities.pop(cid, None)  # the classes changed: start the plot again
        self.classes[cid] = classes
        times = np.asarray(data["timestamps_s"], dtype=np.float64).reshape(-1)
        probs = np.asarray(data["probabilities"], dtype=np.float64).reshape(len(times), -1)
        self.probabilities.setdefault(cid, _Series()).add(times, probs)

    # --- the frame ---------------------------------------------------------------------------

    def frame(self) -> dict[str, Any]:
        """The page's picture now, as plain JSON values (cached until something changes)."""
        if self._frame is not None and self._frame_version == self.version:
            return self._frame
        last = self.movements[-1] if self.movements else None
        interaction = {}
        for cid, series in self.probabilities.items():
            probs = series.values[-1][-1]
            best = int(np.nanargmax(probs)) if np.isfinite(probs).any() else 0
            interaction[cid] = {"class": self.classes[cid][best],
                                "probability": round(float(probs[best]), 4)}
        self._frame = {
            "t_s": round(self.t_s, 4),
            "status": self.status,
            "reason": self.reason,
            "preferred_map": self.preferred_map,
            "wall_s": round(self._clock() - self._started, 3),
            "phase": None if last is None else last.get("phase"),
            "maps": {mid: self._map_frame(mid, m) for mid, m in sorted(self.maps.items())},
            "scene": self._scene_frame(),
            "paths": {rid: self._path_frame(p) for rid, p in sorted(self.paths.items())},
            "movements": [{k: m.get(k) for k in (
                "index", "start_m", "end_m", "phase", "label", "halted", "halt_reason",
                "final_class", "max_force_n", "final_position_m")} for m in self.movements],
            "forces": {name: self._series_frame(s) for name, s in sorted(self.forces.items())},
            "probabilities": {cid: {"classes": self.classes[cid], **self._series_frame(s)}
                              for cid, s in sorted(self.probabilities.items())},
            "interaction": interaction,
            "metrics": self._metrics_frame(),
            "errors": dict(self.errors),
            "counts": {"map_versions": sum(m.version for m in self.maps.values()),
                       "path_points": sum(len(p.points) for p in self.paths.values()),
                       "force_samples": sum(s.count for s in self.forces.values()),
                       "messages": self.messages, "dropped": self.dropped},
        }
        self._frame_version = self.version
        return self._frame

    def _metrics_frame(self) -> dict[str, Any]:
        so_far: dict[str, Any] = {
            "model_time_s": round(self.t_s, 3),
            "movements": len(self.movements),
            "halted_movements": sum(bool(m.get("halted")) for m in self.movements),
            "safety_halts": len(self.halts),
            "max_force_n": round(self.max_force_n, 3),
            **{f"samples.{sid}": n for sid, n in sorted(self.samples.items())},
        }
        return {**so_far, **self.metrics}

    def _scene_frame(self) -> dict[str, Any]:
        """The region's rectangle and the true objects' outlines (``/scene``)."""
        region = self.scene.get("region")
        objects = [{"id": eid, "shape": e["metadata"].get("shape", ""),
                    "points": _rounded(np.asarray(e["lines"][0]), 5)}
                   for eid, e in sorted(self.scene.items())
                   if eid.startswith("object/") and e["lines"]]
        return {"region": _rounded(np.asarray(region["lines"][0]), 5)
                if region and region["lines"] else None,
                "objects": objects}

    def _map_frame(self, map_id: str, m: _Map) -> dict[str, Any]:
        estimate = self.scene.get(f"estimate/{map_id}")
        if m.frame is not None and m.estimate is estimate:
            return m.frame
        from hapticframe.geometry import main_outline

        grid = m.grid
        mean = grid["mean"]
        rows, columns = mean.shape
        (x0, y0), (dx, dy) = grid["origin_m"], grid["cell_m"]
        outline: list[Any] = []
        source = "none"
        if estimate is not None and estimate["lines"]:
            # The recording's own estimate (the blob the evaluation would outline).
            outline, source = [_rounded(np.asarray(estimate["lines"][0]), 5)], "recording"
        elif map_id not in self._estimated and rows >= 2 and columns >= 2 \
                and np.isfinite(mean).all():
            # A recording without estimates on /scene: the same curve, from the grid.
            xs = x0 + (np.arange(columns) + 0.5) * dx
            ys = y0 + (np.arange(rows) + 0.5) * dy
            line = main_outline(xs, ys, mean, OUTLINE_LEVEL)
            if line is not None:
                outline, source = [_rounded(line, 5)], "grid"
        std = grid["std"]
        scale = STD_SCALE if std is None else std_scale(std)
        m.estimate = estimate
        m.frame = {
            "version": m.version, "t_s": round(m.t_s, 4), "rows": rows, "columns": columns,
            "origin_m": grid["origin_m"], "cell_m": grid["cell_m"],
            "mean": _bytes(mean, 1.0),
            "std": None if std is None else _bytes(std, scale), "std_scale": scale,
            "max_mean": round(float(np.nanmax(mean)), 4) if mean.size else 0.0,
            "outline": outline, "outline_level": _level(estimate), "outline_source": source,
        }
        return m.frame

    @staticmethod
    def _path_frame(path: _Path) -> dict[str, Any]:
        points = np.asarray(path.points, dtype=np.float64).reshape(-1, 2)
        movements = np.asarray(path.movements, dtype=np.int64)
        current = movements == path.movement
        earlier = ~current
        step = _thin(int(earlier.sum()), MAX_PATH_POINTS)
        # One polyline per movement: no line drawn across the travel between two movements.
        kept, indices = points[earlier][step], movements[earlier][step]
        cuts = np.flatnonzero(np.diff(indices)) + 1
        return {"points": [_rounded(part, 5) for part in np.split(kept, cuts) if len(part)],
                "current": _rounded(points[current][_thin(int(current.sum()), 2000)], 5),
                "movement": path.movement,
                "position_m": _rounded(points[-1], 5) if len(points) else None,
                "depth_m": None if math.isnan(path.depth_m) else round(path.depth_m, 4)}

    @staticmethod
    def _series_frame(series: _Series) -> dict[str, Any]:
        t, v = series.window()
        return {"t_s": _rounded(t), "values": _rounded(v)}


@dataclass
class RecordingTimeline:
    """A finished or recovered recording's messages in time order, and the page's frame at
    any time of it (``hapticframe view``'s slider).

    ``state_at`` folds forward from the last time asked, or again from the start when the
    time goes back.
    """

    messages: Sequence[Message]
    _state: LiveState | None = None
    _next: int = 0
    _t_s: float = -math.inf

    @classmethod
    def from_recording(cls, by_topic: Mapping[str, Sequence[tuple[int, Mapping[str, Any]]]],
                       ) -> RecordingTimeline:
        """From :func:`~hapticframe.record._recording.read_recording`'s output."""
        merged = [(ns, topic, data) for topic, items in by_topic.items() for ns, data in items]
        merged.sort(key=lambda item: item[0])  # stable: file order among equal times
        return cls([(topic, ns / 1e9, data) for ns, topic, data in merged])

    @property
    def start_s(self) -> float:
        return self.messages[0][1] if self.messages else 0.0

    @property
    def end_s(self) -> float:
        return self.messages[-1][1] if self.messages else 0.0

    @property
    def evaluated_map(self) -> str | None:
        """The map the run scored (its final ``/metrics``), the one the page shows first."""
        for topic, _, data in reversed(self.messages):
            if topic == METRICS.name:
                metrics = data.get("metrics")
                found = metrics.get("evaluated_map") if isinstance(metrics, Mapping) else None
                return found if isinstance(found, str) else None
        return None

    def state_at(self, t_s: float) -> LiveState:
        if self._state is None or t_s < self._t_s:
            self._state, self._next = LiveState(), 0
            self._state.preferred_map = self.evaluated_map
        state = self._state
        while self._next < len(self.messages) and self.messages[self._next][1] <= t_s:
            state.fold(*self.messages[self._next])
            self._next += 1
        self._t_s = t_s
        status = "recording" if self._next < len(self.messages) else "recording (end)"
        if state.status != status:
            state.status = status
            state.version += 1
        return state

    def frame_at(self, t_s: float) -> dict[str, Any]:
        frame = dict(self.state_at(t_s).frame())
        frame["timeline"] = {"start_s": self.start_s, "end_s": self.end_s,
                             "t_s": min(max(t_s, self.start_s), self.end_s)}
        return frame
