"""``run.mcap``: every run recorded as it happens, and ``hapticframe recover``.

A run writes its recording with the ``mcap`` library into its staging folder
(``DIR/.hapticframe-partial/run.mcap``, see :class:`~hapticframe.run._results.OutputDir`),
which moves to ``DIR/run.mcap`` with the other results when the run ends in any way. A run
killed outright (``kill -9``, power loss) leaves the recording in the staging folder,
complete up to its last sync; ``hapticframe recover DIR`` writes what it holds as a
complete, indexed ``DIR/run.mcap`` (:mod:`hapticframe.record._recover`).

Channels (JSON messages, ``jsonschema`` schemas named ``hapticframe.*``) hold arrays per
block of samples, never one message per sample. Every topic and its schema is one entry of
the channel table, :data:`hapticframe.run._channels.CHANNELS`; a topic outside it, or written
with another schema, raises :class:`~hapticframe.run._channels.ChannelError`.

The ``/loop`` events carry the cumulative counts of committed sensor samples and robot
states at each stream start, locate and map flush: ``hapticframe replay`` re-cuts the
recorded streams at exactly those points, whatever the blocks' sizes. The metadata record
``hapticframe`` holds the experiment's resolved configuration (``config``, JSON).

Foxglove's well-known schemas (:mod:`hapticframe.record._foxglove`), so that the file opens in
Foxglove or Lichtblick: ``/map/ID/grid`` (``foxglove.Grid``: the map's occupancy mean and
std on a grid, at ``run.snapshot_rate_hz`` of model time), ``/scene``
(``foxglove.SceneUpdate``: the region and the true objects once at the start, the
estimated outline with each snapshot) and ``/robot/ID/pose`` (``foxglove.PoseInFrame``,
at the snapshot rate). docs/recording.md lists every channel.

Timing: a message's log time is the run's model time (the samples' own clock, in ns) of
its last sample. Samples of one channel gather into one message until the model time has
advanced :data:`BLOCK_S` past the block's start; at least every :data:`SYNC_S` seconds of
wall-clock time every open block is written out, the chunk in progress is closed (chunks
are small, :data:`CHUNK_BYTES`) and the file is ``fsync``-ed, so a ``kill -9`` loses at
most about that second. Non-finite floats are written as JSON ``null`` (read back as NaN).

Listeners (:meth:`RunRecording.add_listener`, or :func:`listening` for every recording
opened meanwhile) see each message right after it is written, decoded: the live view
(:mod:`hapticframe.live`) is one. A listener must return at once; one that raises is
logged once and dropped, never failing the run.
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
from bisect import bisect_left
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from operator import itemgetter
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

import numpy as np
import orjson

from hapticframe._atomic import output_error
from hapticframe._errors import UsageError
from hapticframe._version import __version__
from hapticframe.record import _foxglove
from hapticframe.run._channels import (
    CLASSIFIER,
    DEVICE_HEALTH,
    FEATURES,
    LOCATED,
    MAP_GRID,
    MOVEMENT,
    OBSERVATIONS,
    ROBOT_POSE,
    ROBOT_STATE,
    SCENE,
    SENSOR,
    MapSnapshot,
    check_topic,
)

if TYPE_CHECKING:
    from hapticframe._scene import Scene
    from hapticframe.kinds import (
        ClassProbabilities,
        LocatedMeasurement,
        MovementResult,
        Observations,
        RobotState,
        SampleBatch,
    )

__all__ = [
    "BLOCK_S",
    "CHUNK_BYTES",
    "RECORDING",
    "SNAPSHOT_RATE_HZ",
    "SNAPSHOT_SPACING_M",
    "SYNC_S",
    "RunRecording",
    "decode_message",
    "encode_message",
    "find_recording",
    "listening",
    "open_run_recording",
    "read_recording",
]

_log = logging.getLogger("hapticframe.recording")

#: The recording's file name inside a run's directory.
RECORDING = "run.mcap"
#: Wall-clock seconds between two syncs (open blocks written, chunk closed, ``fsync``).
SYNC_S = 1.0
#: Model-time seconds of samples one message of a channel holds at most (about).
BLOCK_S = 0.1
#: Wall-clock seconds a run's recording lets pass between two writes of its blocks: a
#: simulated run, far faster than real time, then writes a few large messages rather than
#: one per 0.1 s of model time (a 10 x 10 m search: 100,000 messages, a third of its CPU).
EMIT_WALL_S = 0.05
#: The size at which a chunk is closed before a sync would close it (bytes, uncompressed).
CHUNK_BYTES = 256 * 1024
#: Map snapshots (and fingertip poses) per second of model time, unless the run says.
SNAPSHOT_RATE_HZ = 5.0
#: The snapshots' grid spacing (metres), unless the run says.
SNAPSHOT_SPACING_M = 0.01
#: Model times this close count as equal when snapshots are due (steps of 0.01 s add up
#: to a little less than their sum).
#: Robot steps held before they go into their block (without a sensor's samples to
#: move the blocks on).
_ROBOT_ROWS_HELD = 256
_EPS_S = 1e-6
#: The first bytes of every MCAP file.
MAGIC = b"\x89MCAP0\r\n"

#: ``fn(topic, t_s, data)``: called with every message a recording writes (decoded).
Listener = Callable[[str, float, Mapping[str, Any]], None]
#: Listeners every :class:`RunRecording` gets when it opens (see :func:`listening`).
_GLOBAL_LISTENERS: list[Listener] = []


@contextmanager
def listening(listener: Listener) -> Iterator[None]:
    """Give ``listener`` to every :class:`RunRecording` opened inside the block (``hapticframe
    run --live`` watches the run it starts without reaching into the orchestrator)."""
    _GLOBAL_LISTENERS.append(listener)
    try:
        yield
    finally:
        _GLOBAL_LISTENERS.remove(listener)


_ARRAY = {"type": "array"}
_NUMBERS = {"type": "array", "items": {"type": ["number", "null", "array"]}}


def _schema(title: str, properties: Mapping[str, Any], required: list[str]) -> dict[str, Any]:
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": title,
            "type": "object", "properties": dict(properties), "required": required}


_BY_NAME = {"type": "object", "additionalProperties": _ARRAY}
#: The JSON schema of every message, by schema name.
SCHEMAS: dict[str, dict[str, Any]] = {
    "hapticframe.SampleBatch": _schema(
        "Samples of a sensor or feature extractor (arrays: one row per sample)",
        {"timestamps_s": _NUMBERS, "channels": _BY_NAME, "valid": _BY_NAME,
         "units": {"type": "object", "additionalProperties": {"type": "string"}},
         "rates_hz": {"type": "object", "additionalProperties": {"type": "number"}}},
        ["timestamps_s", "channels"]),
    "hapticframe.ClassProbabilities": _schema(
        "A classifier's output", {"timestamps_s": _NUMBERS, "probabilities": _NUMBERS,
                                  "classes": {"type": "array", "items": {"type": "string"}}},
        ["timestamps_s", "probabilities", "classes"]),
    "hapticframe.LocatedMeasurement": _schema(
        "Where each classified sample was taken", {
            "timestamps_s": _NUMBERS, "positions_m": _NUMBERS, "headings_rad": _NUMBERS,
            "depths_m": _NUMBERS},
        ["timestamps_s", "positions_m", "headings_rad", "depths_m"]),
    "hapticframe.Observations": _schema(
        "A sensor model's observations, the maps' input",
        {"points_m": _NUMBERS, "targets": _NUMBERS, "weights": _NUMBERS},
        ["points_m", "targets", "weights"]),
    "hapticframe.RobotStates": _schema(
        "A robot's states", {"timestamps_s": _NUMBERS, "positions_m": _NUMBERS,
                             "headings_rad": _NUMBERS, "depths_m": _NUMBERS,
                             "movement_index": _NUMBERS},
        ["timestamps_s", "positions_m", "headings_rad", "depths_m", "movement_index"]),
    "hapticframe.MovementResult": _schema(
        "An exploratory movement and how it ended", {
            "index": {"type": "integer"}, "start_m": _ARRAY, "end_m": _ARRAY,
            "speed_m_per_s": {"type": "number"}, "depth_m": {"type": ["number", "null"]},
            "phase": {"type": "string"}, "label": {"type": "string"},
            "halted": {"type": "boolean"}, "halt_reason": {"type": "string"},
            "final_class": {"type": "string"}, "max_force_n": {"type": ["number", "null"]},
            "final_position_m": {"type": ["array", "null"]}, "extra": {"type": "object"}},
        ["index", "start_m", "end_m", "halted", "halt_reason"]),
    "hapticframe.SafetyHalt": _schema(
        "A halt of the run loop's safety checks (run.json: details.safety_halts)",
        {"reason": {"type": "string"}}, ["reason"]),
    "hapticframe.LoopEvent": _schema(
        "A point of the run loop that replay must repeat (cumulative counts so far)", {
            "event": {"enum": ["stream_start", "locate_from", "flush_maps"]},
            "t_s": {"type": ["number", "null"]},
            "counts": {"type": "object", "additionalProperties": {"type": "integer"}},
            "keep_force": {"type": "boolean"}},
        ["event", "t_s", "counts", "keep_force"]),
    "hapticframe.RunMetrics": _schema(
        "A finished run's metrics.json and each component's own finalize() metrics",
        {"metrics": {"type": "object"}, "components": {
            "type": "object", "additionalProperties": {"type": "object"}}},
        ["metrics", "components"]),
    "hapticframe.DeviceHealth": _schema(
        "A device's health counters", {"counters": {
            "type": "object", "additionalProperties": {"type": "integer"}}}, ["counters"]),
    **_foxglove.SCHEMAS,
}

#: Colours (r, g, b, a) of the scene's lines: region, true objects, estimated outlines.
_REGION_COLOUR = (0.5, 0.5, 0.5, 1.0)
_TRUTH_COLOUR = (0.17, 0.63, 0.17, 1.0)  # matplotlib's tab:green, as on the figures
_ESTIMATE_COLOUR = (1.0, 1.0, 1.0, 1.0)


def _plain(array: np.ndarray) -> Any:
    """``array`` as nested lists, non-finite floats as None (JSON has no NaN)."""
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        objects = array.astype(object)
        objects[~np.isfinite(array)] = None
        return objects.tolist()
    return array.tolist()


def _json_fallback(value: Any) -> Any:
    """What the serializer does not take as it is: numpy arrays it cannot read in place
    (not C-contiguous, another byte order or dtype) and numpy scalars, as Python values."""
    if isinstance(value, np.ndarray):
        if value.dtype.kind == "f":
            return np.ascontiguousarray(value, dtype=np.float64)
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"a recording message cannot hold {type(value).__name__}")


_JSON_OPTIONS = orjson.OPT_SERIALIZE_NUMPY


def encode_message(data: Mapping[str, Any]) -> bytes:
    """A message as ``run.mcap`` holds it: JSON, non-finite floats as null, numpy arrays as
    arrays (orjson, which reads a float64 array in place: the same JSON as :func:`json.dumps`
    of the array's list, about 4x faster than making the list first)."""
    try:
        return orjson.dumps(data, default=_json_fallback, option=_JSON_OPTIONS)
    except orjson.JSONEncodeError as exc:
        if isinstance(exc.__cause__, TypeError):  # raised by _json_fallback: not JSON
            raise exc.__cause__ from None
    # What orjson refuses to read in place (a big-endian array): as Python values.
    try:
        return orjson.dumps(_nan_to_none(data), default=_json_fallback)
    except orjson.JSONEncodeError as exc:
        raise TypeError(f"a recording message cannot be written as JSON: {exc}") from exc


def decode_message(payload: bytes) -> Any:
    """A message of ``run.mcap`` decoded (its nulls stay None)."""
    return orjson.loads(payload)


def _nan_to_none(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_nan_to_none(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value)
    if isinstance(value, np.generic):
        return _nan_to_none(value.item())
    return value


#: A held robot row's model time (its first field).
_row_time = itemgetter(0)


@dataclass
class _Block:
    """One channel's samples waiting to become a message."""

    schema: str
    #: Array fields (a key path into the message) and their parts, in arrival order.
    parts: dict[tuple[str, ...], list[np.ndarray]] = field(default_factory=dict)
    #: Rows of per-sample scalars (robot states), turned into arrays when written.
    rows: list[tuple[Any, ...]] = field(default_factory=list)
    row_fields: tuple[str, ...] = ()
    constant: dict[str, Any] = field(default_factory=dict)
    start_s: float = math.nan
    end_s: float = 0.0


class RunRecording:
    """Writes ``run.mcap`` while the run runs; see the module's notes for its channels.

    Parameters
    ----------
    path : Path
        The file to write (the run's staging folder).
    metadata : mapping of str to str
        Written as the recording's ``hapticframe`` metadata record (name, seed, ...).
    sync_s, block_s : float
        Wall-clock seconds between syncs; model-time seconds a message's block spans.
    emit_wall_s : float
        The fewest wall-clock seconds between two writes of the blocks (0: every
        ``block_s`` of model time); a block then spans more model time.
    clock : callable
        The wall clock syncs are timed on (tests pass a fake one).
    """

    def __init__(self, path: Path, metadata: Mapping[str, str] | None = None, *,
                 sync_s: float = SYNC_S, block_s: float = BLOCK_S,
                 emit_wall_s: float = 0.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        try:
            self._file: BinaryIO = open(self.path, "wb")  # closed by close()
        except OSError as exc:
            raise output_error(self.path, exc) from exc
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES,
                              compression=CompressionType.ZSTD)
        self._sync_s = sync_s
        self._block_s = block_s
        self._emit_wall_s = emit_wall_s
        self._clock = clock
        self._last_sync = clock()
        self._last_emit = -math.inf
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}  # topic: (channel id, schema)
        self._blocks: dict[str, _Block] = {}
        # Events written with the next blocks, not now: a map flush must not cut every
        # channel's block short (see later()).
        self._deferred: list[tuple[str, str, float, dict[str, Any]]] = []
        self._sequence = 0
        self._now_s = 0.0  # the latest model time seen
        self._emit_after_s = math.inf  # the earliest end of an open block
        self.messages = 0
        self._listeners: list[Listener] = list(_GLOBAL_LISTENERS)
        #: How many of the session's safety halts are recorded (the loop keeps it).
        self.halts_recorded = 0
        self.closed = False
        # Snapshots (contract B): their rate set by configure_snapshots, the run's setting.
        self.snapshot_rate_hz = SNAPSHOT_RATE_HZ
        self._next_snapshot_s = -math.inf
        self._robot_lanes: dict[str, list[Any]] = {}
        # (t, x, y, heading, depth, movement): flat tuples of numbers, which the garbage
        # collector stops tracking (a 10 x 10 m search holds up to a block of them).
        self._robot_rows: dict[str, list[tuple[float, float, float, float, float, int]]] = {}
        self._scene_written = False
        self._guard(lambda: self._writer.start(profile="", library=f"hapticframe {__version__}"))
        if metadata:
            self._guard(lambda: self._writer.add_metadata("hapticframe", dict(metadata)))
        self.sync()

    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(topic, t_s, data)`` with every message written from now on, after
        it is written (``data`` the decoded message; do not change it). It must not block:
        the run's thread calls it. One that raises is logged once and dropped. A listener
        with a true ``wants_payload`` attribute is called ``listener(topic, t_s, data,
        payload)``, ``payload`` the message's JSON bytes as written."""
        self._listeners.append(listener)

    def remove_listener(self, listener: Listener) -> None:
        """Stop calling ``listener`` (nothing happens when it is not listening)."""
        if listener in self._listeners:
            self._listeners.remove(listener)

    def _tell(self, topic: str, t_s: float, data: Mapping[str, Any], payload: bytes) -> None:
        decoded: Any = None
        for listener in list(self._listeners):
            try:
                if getattr(listener, "wants_payload", False):
                    # A listener that sends the message on (run --foxglove) takes the bytes
                    # just written rather than encoding them a second time.
                    listener(topic, t_s, data, payload)  # type: ignore[call-arg]
                else:
                    if decoded is None:  # the message as a reader sees it: lists, None
                        decoded = decode_message(payload)
                    listener(topic, t_s, decoded)
            except Exception as exc:  # a listener never fails the run
                _log.warning("recording listener %r failed on %s and is dropped: %s: %s",
                             getattr(listener, "__qualname__", listener), topic,
                             type(exc).__name__, exc)
                self.remove_listener(listener)

    # --- what the run records ------------------------------------------------------------

    def samples(self, kind: str, cid: str, batch: SampleBatch,
                units: Mapping[str, str] | None = None,
                rates_hz: Mapping[str, float] | None = None) -> None:
        """A sensor's or feature extractor's batch (``kind``: ``sensor`` or
        ``feature_extractor``); a sensor's channel units and nominal rates with it (a
        replayed sensor declares the same rates: a filter designed on them must match)."""
        if not len(batch):
            return
        channel = SENSOR if kind == "sensor" else FEATURES
        block = self._block(channel.topic(cid), channel.schema)
        if units and "units" not in block.constant:
            block.constant["units"] = dict(units)
        if rates_hz and "rates_hz" not in block.constant:
            block.constant["rates_hz"] = {k: float(v) for k, v in rates_hz.items()}
        self._add(block, batch.timestamps_s, {("timestamps_s",): batch.timestamps_s,
                  **{("channels", n): a for n, a in batch.channels.items()},
                  **{("valid", n): a for n, a in batch.valid.items()}})

    def probabilities(self, cid: str, probs: ClassProbabilities) -> None:
        if not len(probs):
            return
        topic = CLASSIFIER.topic(cid)
        block = self._block(topic, CLASSIFIER.schema)
        classes = list(probs.classes)
        if block.constant.get("classes", classes) != classes:
            self._emit(topic)
            block = self._block(topic, CLASSIFIER.schema)
        block.constant["classes"] = classes
        self._add(block, probs.timestamps_s, {("timestamps_s",): probs.timestamps_s,
                                              ("probabilities",): probs.probabilities})

    def located(self, sm_id: str, located: LocatedMeasurement) -> None:
        block = self._block(LOCATED.topic(sm_id), LOCATED.schema)
        self._add(block, located.timestamps_s, {
            ("timestamps_s",): located.timestamps_s, ("positions_m",): located.positions_m,
            ("headings_rad",): located.headings_rad, ("depths_m",): located.depth_m})

    def observations(self, sm_id: str, obs: Observations, t_s: float) -> None:
        block = self._block(OBSERVATIONS.topic(sm_id), OBSERVATIONS.schema)
        self._add(block, np.array([t_s]), {("points_m",): obs.points_m,
                                           ("targets",): obs.targets,
                                           ("weights",): obs.weights})

    def robot_state(self, robot_id: str, state: RobotState, movement_index: int) -> None:
        """One robot step, held as a row until the next blocks are written (the closed loop
        takes some 20,000 of them, a 10 x 10 m search 460,000: taken one by one into the
        blocks they cost that recording 10 % of the run's CPU)."""
        rows = self._robot_rows.get(robot_id)
        if rows is None:
            rows = self._robot_rows[robot_id] = []
        x, y = state.position_m.tolist()
        rows.append((float(state.timestamp_s), x, y, float(state.heading_rad),
                     float(state.depth_m), movement_index))
        if len(rows) >= _ROBOT_ROWS_HELD:  # a run with no sensor to move the blocks on
            self._take_robot_rows()

    def _take_robot_rows(self) -> None:
        """Move the robots' held rows into their blocks, with a pose message at
        ``snapshot_rate_hz`` of model time."""
        for robot_id, rows in list(self._robot_rows.items()):
            if not rows:
                continue
            self._robot_rows[robot_id] = []
            lane = self._robot_lanes.get(robot_id)
            if lane is None:  # [topic, time of the next pose message]
                lane = self._robot_lanes[robot_id] = [ROBOT_STATE.topic(robot_id), -math.inf]
            block = self._blocks.get(lane[0])
            if block is None:
                block = self._block(lane[0], ROBOT_STATE.schema)
                block.row_fields = ("timestamps_s", "x", "y", "headings_rad", "depths_m",
                                    "movement_index")
            block.rows.extend(rows)
            if self.snapshot_rate_hz > 0:
                period, due = 1.0 / self.snapshot_rate_hz, lane[1]
                # The steps come in time order: the next pose is found by bisection, not
                # by looking at each of the hundreds of steps between two poses.
                k = bisect_left(rows, due, key=_row_time)
                while k < len(rows):
                    t, x, y, heading, depth, _ = rows[k]
                    due = t + period - _EPS_S
                    # Deferred, not an event: an event writes every open block first, and
                    # poses at the snapshot rate would cut a long run's blocks into tens of
                    # thousands of small messages.
                    self.later(ROBOT_POSE.topic(robot_id), ROBOT_POSE.schema,
                               _foxglove.pose_message(t, (x, y), heading, depth), t,
                               plain=True)
                    k = bisect_left(rows, due, lo=k + 1, key=_row_time)
                lane[1] = due
            self._seen(block, rows[0][0], rows[-1][0])

    def movement(self, result: MovementResult) -> None:
        """An exploratory movement's result (written at once, with every open block)."""
        m = result.movement
        final = result.final_state
        self.event(MOVEMENT.name, MOVEMENT.schema, {
            "index": result.index, "start_m": m.start_m, "end_m": m.end_m,
            "speed_m_per_s": m.speed_m_per_s, "depth_m": m.depth_m, "phase": m.phase,
            "label": m.label, "halted": result.halted, "halt_reason": result.halt_reason,
            "final_class": result.final_class, "max_force_n": result.max_force_n,
            "final_position_m": None if final is None else final.position_m,
            "extra": {k: v if isinstance(v, (str, int, float, bool, list, tuple)) else repr(v)
                      for k, v in result.extra.items()},
        })

    def event(self, topic: str, schema: str, data: Mapping[str, Any],
              t_s: float | None = None) -> None:
        """One message now (open blocks are written first, so the file stays in time order)."""
        self.flush_blocks()
        when = self._now_s if t_s is None else max(float(t_s), 0.0)
        self._write(topic, schema, when, _nan_to_none(dict(data)))
        self._maybe_sync()

    def later(self, topic: str, schema: str, data: Mapping[str, Any], t_s: float, *,
              plain: bool = False) -> None:
        """One message written with the next blocks (at the latest at the next sync or
        close), so that frequent events do not cut the open blocks into small messages.
        Its log time is ``t_s``; readers order such messages by their content, not by
        their place in the file. ``plain``: ``data`` holds finite Python values only (a
        pose message), taken as it is."""
        self._deferred.append((topic, schema, max(float(t_s), 0.0),
                               dict(data) if plain else _nan_to_none(dict(data))))

    def health(self, counters: Mapping[str, Mapping[str, int]]) -> None:
        for cid, values in counters.items():
            self.event(DEVICE_HEALTH.topic(cid), DEVICE_HEALTH.schema,
                       {"counters": {k: int(v) for k, v in values.items()}})

    # --- Foxglove: map snapshots, the scene ----------------------------------------------

    @property
    def now_s(self) -> float:
        """The latest model time the recording has seen (seconds)."""
        if self._robot_rows:
            self._take_robot_rows()
        return self._now_s

    def configure_snapshots(self, rate_hz: float) -> None:
        """Snapshots and poses per second of model time (0: none)."""
        if self._robot_rows:
            self._take_robot_rows()  # the steps so far under the rate they came at
        self.snapshot_rate_hz = float(rate_hz)

    def snapshot_due(self, t_s: float | None = None) -> bool:
        """True when a map snapshot is due at ``t_s`` (default: now), and the next one is
        then counted from ``t_s``."""
        if self.snapshot_rate_hz <= 0:
            return False
        t = self.now_s if t_s is None else float(t_s)
        if t < self._next_snapshot_s - _EPS_S:
            return False
        self._next_snapshot_s = t + 1.0 / self.snapshot_rate_hz
        return True

    def scene(self, scene: Scene | None) -> None:
        """``/scene`` once, at model time 0: the region's rectangle and the true objects'
        outlines (later calls write nothing)."""
        if self._scene_written or scene is None:
            return
        self._scene_written = True
        r = scene.region
        entities = [_foxglove.line_entity(
            "region", 0.0, [(r.x_min_m, r.y_min_m), (r.x_max_m, r.y_min_m),
                            (r.x_max_m, r.y_max_m), (r.x_min_m, r.y_max_m)],
            _REGION_COLOUR, thickness_m=0.002, metadata={"kind": "region"})]
        for index, obj in enumerate(scene.objects):
            entities.append(_foxglove.line_entity(
                f"object/{index}", 0.0, obj.outline(128), _TRUTH_COLOUR,
                metadata={"kind": "true object", "shape": str(obj.shape)}))
        self.event(SCENE.name, SCENE.schema, _foxglove.scene_update(entities), 0.0)

    def map_snapshot(self, snapshot: MapSnapshot) -> None:
        """``/map/MAP_ID/grid``: the snapshot's mean and std, and on ``/scene`` its estimated
        outline (removed while there is none). The run makes the snapshot."""
        t_s, map_id = snapshot.t_s, snapshot.map_id
        self.event(MAP_GRID.topic(map_id), MAP_GRID.schema, _foxglove.grid_message(
            t_s, snapshot.origin_m, snapshot.cell_m, snapshot.mean, snapshot.std), t_s)
        entity_id = f"estimate/{map_id}"
        if snapshot.outline is None:
            update = _foxglove.scene_update([], [entity_id], t_s)
        else:
            update = _foxglove.scene_update([_foxglove.line_entity(
                entity_id, t_s, snapshot.outline, _ESTIMATE_COLOUR, metadata={
                    "kind": "estimated outline", "map": map_id,
                    "level": f"{snapshot.outline_level:g}"})])
        self.event(SCENE.name, SCENE.schema, update, t_s)

    # --- blocks, syncs -------------------------------------------------------------------

    def _block(self, topic: str, schema: str) -> _Block:
        block = self._blocks.get(topic)
        if block is None or block.schema != schema:
            check_topic(topic, schema)  # raises on a schema other than the channel's
        if block is None:
            block = self._blocks[topic] = _Block(schema)
        return block

    def _add(self, block: _Block, times: np.ndarray,
             arrays: Mapping[tuple[str, ...], np.ndarray]) -> None:
        for key, array in arrays.items():
            block.parts.setdefault(key, []).append(np.asarray(array))
        if len(times):
            self._seen(block, float(times[0]), float(times[-1]))
        self._maybe_sync()

    def _seen(self, block: _Block, first: float, last: float) -> None:
        if math.isnan(block.start_s):
            block.start_s = first
            self._emit_after_s = min(self._emit_after_s, first + self._block_s)
        block.end_s = max(block.end_s, last)
        if last > self._now_s:
            self._now_s = last
            if last >= self._emit_after_s and (
                    self._emit_wall_s <= 0
                    or self._clock() - self._last_emit >= self._emit_wall_s):
                self.flush_blocks()

    def _maybe_sync(self) -> None:
        if self._clock() - self._last_sync >= self._sync_s:
            self.sync()

    def flush_blocks(self) -> None:
        """Write every open block as one message per channel."""
        if self._robot_rows:
            self._take_robot_rows()
        for topic in list(self._blocks):
            self._emit(topic)
        self._emit_after_s = math.inf
        if self._emit_wall_s > 0:
            self._last_emit = self._clock()
        deferred, self._deferred = self._deferred, []
        for topic, schema, t_s, data in deferred:
            self._write(topic, schema, t_s, data)

    def _emit(self, topic: str) -> None:
        block = self._blocks.pop(topic, None)
        if block is None or (not block.parts and not block.rows):
            return
        data: dict[str, Any] = dict(block.constant)
        for key, parts in block.parts.items():
            array = parts[0] if len(parts) == 1 else np.concatenate(parts)
            target = data
            for name in key[:-1]:
                target = target.setdefault(name, {})
            # The array itself: the encoder reads it in place (float64, so that what is
            # read back is the value recorded, to the bit).
            target[key[-1]] = (array.astype(np.float64) if array.dtype.kind == "f"
                               and array.dtype != np.float64 else array)
        if block.rows:
            # Python numbers already (robot_state): columns as they are (the serializer
            # writes a tuple as an array, non-finite numbers as null); x and y as the
            # (n, 2) positions.
            columns = dict(zip(block.row_fields, zip(*block.rows, strict=True), strict=True))
            data["timestamps_s"] = columns["timestamps_s"]
            data["positions_m"] = np.column_stack((np.array(columns["x"], dtype=np.float64),
                                                   np.array(columns["y"], dtype=np.float64)))
            for name in ("headings_rad", "depths_m", "movement_index"):
                data[name] = columns[name]
        self._write(topic, block.schema, block.end_s, data)

    def _write(self, topic: str, schema: str, t_s: float, data: Mapping[str, Any]) -> None:
        known = self._channels.get(topic)
        if known is None or known[1] != schema:
            table = check_topic(topic, schema)  # raises on a schema other than the channel's
            schema_id = self._schemas.get(schema)
            if schema_id is None:
                schema_id = self._schemas[schema] = self._writer.register_schema(
                    name=schema, encoding="jsonschema",
                    data=json.dumps(SCHEMAS[schema]).encode())
            known = self._channels[topic] = (self._writer.register_channel(
                topic=topic, message_encoding=table.encoding, schema_id=schema_id), schema)
        channel = known[0]
        stamp = round(max(t_s, 0.0) * 1e9)
        payload = encode_message(data)
        self._sequence += 1
        self._guard(lambda: self._writer.add_message(
            channel_id=channel, log_time=stamp, publish_time=stamp, data=payload,
            sequence=self._sequence))
        self.messages += 1
        if self._listeners:
            self._tell(topic, max(t_s, 0.0), data, payload)

    def sync(self) -> None:
        """Write every open block, close the chunk in progress and ``fsync`` the file."""
        self.flush_blocks()

        def flush() -> None:
            self._writer.flush()  # type: ignore[no-untyped-call]
            os.fsync(self._file.fileno())

        self._guard(flush)
        self._last_sync = self._clock()

    def close(self) -> None:
        """Write what is left and the file's summary (indexes, statistics); idempotent."""
        if self.closed:
            return
        self.closed = True
        try:
            self.flush_blocks()
            self._guard(self._writer.finish)
            self._guard(lambda: os.fsync(self._file.fileno()))
        finally:
            self._file.close()

    def _guard(self, action: Callable[[], Any]) -> Any:
        try:
            return action()
        except OSError as exc:
            raise output_error(self.path, exc) from exc


def open_run_recording(folder: Path, metadata: Mapping[str, str]) -> RunRecording:
    """``folder/run.mcap``: the :class:`~hapticframe.run._channels.RecordingOpener` that the CLI,
    sweep trials, replay and :func:`hapticframe.run_experiment` hand the run scope."""
    return RunRecording(Path(folder) / RECORDING, metadata, emit_wall_s=EMIT_WALL_S)


# --- reading and recovering ------------------------------------------------------------------


def find_recording(target: Path) -> Path:
    """The recording ``target`` names: a file, or a run's directory (its ``run.mcap``, or
    the one a killed run left in the staging folder)."""
    from hapticframe.run._results import STAGING

    if target.is_dir():
        for candidate in (target / RECORDING, target / STAGING / RECORDING):
            if candidate.is_file():
                return candidate
        raise UsageError(f"{target} holds no recording ({RECORDING}, or {STAGING}/{RECORDING} "
                         "of a killed run); give a run's --out directory or an .mcap file")
    if not target.is_file():
        raise UsageError(f"{target}: no such file or directory")
    return target


def _check_magic(path: Path) -> None:
    try:
        with open(path, "rb") as stream:
            head = stream.read(len(MAGIC))
    except OSError as exc:
        raise UsageError(f"{path} cannot be read: {exc.strerror or exc}") from exc
    if head != MAGIC:
        raise UsageError(f"{path} is not an MCAP recording (its first bytes are not the MCAP "
                         "magic); give the run.mcap a run wrote")


def _records(path: Path, stop: list[str]) -> Iterator[Any]:
    """The records of ``path`` in file order, read as a stream until the end or a cut
    (what stopped the reading goes into ``stop``)."""
    from mcap.stream_reader import StreamReader

    with open(path, "rb") as stream:
        reader = StreamReader(stream, validate_crcs=True)
        try:
            yield from reader.records
        except Exception as exc:  # a cut record (EndOfFile, a short chunk), or a damaged one
            where = stream.tell()
            if type(exc).__name__ in ("CRCValidationError", "ZstdError"):
                stop.append(f"the file is damaged before byte {where}: a chunk fails its check "
                            f"({exc}); `hapticframe recover` keeps what it can read past it")
            else:
                stop.append(f"the file ends inside a record, at byte {where} "
                            f"({type(exc).__name__}{': ' + str(exc) if str(exc) else ''})")


def read_recording(path: Path) -> dict[str, list[tuple[int, dict[str, Any]]]]:
    """Every message of a complete or cut recording, decoded, by topic: ``(log_time_ns,
    data)`` in file order (read as a stream: a cut file gives what it holds)."""
    from mcap.records import Channel, Message

    _check_magic(path)
    channels: dict[int, str] = {}
    out: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    for record in _records(path, []):
        if isinstance(record, Channel):
            channels[record.id] = record.topic
        elif isinstance(record, Message) and record.channel_id in channels:
            out.setdefault(channels[record.channel_id], []).append(
                (record.log_time, decode_message(record.data)))
    return out
