"""The recording's channels in one table, the map snapshots the run hands its writer, and the
writer's protocol.

Every topic a run's recording holds is one :class:`Channel` of :data:`CHANNELS`: its name (or
name pattern, ``/sensor/{id}``), its schema, its message encoding, what writes it and what it
holds. The writer (:mod:`hapticframe.record._recording`) refuses a topic that is not in the
table or that comes with another schema (:func:`check_topic`); replay, report, the live view
and bag import find their topics here (:meth:`Channel.topic`, :meth:`Channel.id_of`).
docs/recording.md lists the same table (a test compares them). Adding a channel is one entry
here, its JSON schema where the writer keeps its schemas, and its test.

The table lives in the run layer because the run writes through :class:`RecordingWriter`;
:mod:`hapticframe.record`, :mod:`hapticframe.live` and bag import read it from here.
"""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from hapticframe._scene import Scene
    from hapticframe.kinds import (
        ClassProbabilities,
        LocatedMeasurement,
        Map,
        MovementResult,
        Observations,
        RobotState,
        SampleBatch,
    )

__all__ = [
    "CHANNELS",
    "Channel",
    "ChannelError",
    "MapSnapshot",
    "RecordingOpener",
    "RecordingWriter",
    "channel_of",
    "check_topic",
]

#: What a ``{id}`` in a channel's name stands for: one component id (no ``/``).
_ID = r"(?P<id>[^/]+)"


class ChannelError(ValueError):
    """A topic that is not in the channel table, or written with another schema than its
    channel's (a bug in the code that writes it, never bad user input)."""


@dataclass(frozen=True)
class Channel:
    """One channel of ``run.mcap``.

    Attributes
    ----------
    name : str
        The topic, or its pattern with one ``{id}`` (a component's id).
    schema : str
        The schema's name (``hapticframe.*`` for ours, ``foxglove.*`` for Foxglove's).
    content : str
        What a message holds, in a few words (docs/recording.md shows it).
    writer : str
        What writes it, in a few words.
    encoding : str
        The message encoding (``json``).
    """

    name: str
    schema: str
    content: str
    writer: str
    encoding: str = "json"

    @property
    def pattern(self) -> re.Pattern[str]:
        return _topic_pattern(self.name)

    @property
    def has_id(self) -> bool:
        return "{id}" in self.name

    def topic(self, cid: str | None = None) -> str:
        """The topic of component ``cid`` (a channel without ``{id}`` takes none)."""
        if self.has_id != (cid is not None):
            raise ChannelError(f"channel {self.name} takes {'an id' if self.has_id else 'no id'}")
        return self.name if cid is None else self.name.replace("{id}", cid)

    def id_of(self, topic: str) -> str | None:
        """The component id in ``topic`` when it is this channel's (``""`` for a channel
        without ``{id}``), else None."""
        match = self.pattern.match(topic)
        if match is None:
            return None
        return match["id"] if self.has_id else ""


SENSOR = Channel("/sensor/{id}", "hapticframe.SampleBatch",
                 "timestamps, channels, validity, units, rates", "the dataflow, bag import")
FEATURES = Channel("/feature_extractor/{id}", "hapticframe.SampleBatch",
                   "the extractor's output", "the dataflow")
CLASSIFIER = Channel("/classifier/{id}", "hapticframe.ClassProbabilities",
                     "classes, probabilities", "the dataflow")
LOCATED = Channel("/sensor_model/{id}/located", "hapticframe.LocatedMeasurement",
                  "where each sample was", "the dataflow")
OBSERVATIONS = Channel("/sensor_model/{id}/observations", "hapticframe.Observations",
                       "the maps' input", "the dataflow")
ROBOT_STATE = Channel("/robot/{id}/state", "hapticframe.RobotStates",
                      "poses, movement index", "the dataflow")
ROBOT_POSE = Channel("/robot/{id}/pose", "foxglove.PoseInFrame",
                     "the fingertip's pose at the snapshot rate", "the writer, with each state")
MOVEMENT = Channel("/movement", "hapticframe.MovementResult",
                   "one per movement (halts)", "the loop")
SAFETY_HALT = Channel("/safety_halt", "hapticframe.SafetyHalt",
                      "a safety check's halt", "the loop")
DEVICE_HEALTH = Channel("/device/{id}/health", "hapticframe.DeviceHealth",
                        "the device's counters", "the run scope, at the end")
LOOP = Channel("/loop", "hapticframe.LoopEvent",
               "stream starts, locates, map flushes (cumulative counts)", "the dataflow")
METRICS = Channel("/metrics", "hapticframe.RunMetrics",
                  "a finished run's metrics", "the run scope, at the end")
MAP_GRID = Channel("/map/{id}/grid", "foxglove.Grid",
                   "the map's mean and std on a grid", "the dataflow's snapshots")
SCENE = Channel("/scene", "foxglove.SceneUpdate",
                "region and true objects at the start, then each estimated outline",
                "the dataflow (scene, snapshots)")

#: Every channel of ``run.mcap``, in the order docs/recording.md lists them.
CHANNELS: tuple[Channel, ...] = (
    SENSOR, FEATURES, CLASSIFIER, LOCATED, OBSERVATIONS, ROBOT_STATE, ROBOT_POSE, MOVEMENT,
    SAFETY_HALT, DEVICE_HEALTH, LOOP, METRICS, MAP_GRID, SCENE,
)


@functools.cache
def _topic_pattern(name: str) -> re.Pattern[str]:
    """The regular expression of a channel's topics (made once per channel: the writer
    matches every block it opens)."""
    return re.compile("^" + re.escape(name).replace(re.escape("{id}"), _ID) + "$")


def channel_of(topic: str) -> Channel | None:
    """The channel ``topic`` belongs to, or None when no channel of the table has it."""
    for channel in CHANNELS:
        if channel.id_of(topic) is not None:
            return channel
    return None


def check_topic(topic: str, schema: str) -> Channel:
    """The channel of ``topic``; raises :class:`ChannelError` when the table has none or
    when its schema is not ``schema``."""
    channel = channel_of(topic)
    if channel is None:
        raise ChannelError(f"topic {topic!r} is in no channel of the table "
                           "(hapticframe.run._channels.CHANNELS)")
    if channel.schema != schema:
        raise ChannelError(f"topic {topic!r} is written with schema {schema!r}; its channel "
                           f"{channel.name} has {channel.schema!r}")
    return channel


def snapshot_spacing(width_m: float, height_m: float, spacing_m: float, max_cells: int
                     ) -> float:
    """The spacing of a snapshot grid over a ``width_m`` x ``height_m`` region: ``spacing_m``,
    or the smallest coarser one whose grid has at most ``max_cells`` cells.

    A snapshot's query costs in proportion to its cells, so a fixed spacing over a large
    region would make the recording dominate the run (3 x 2 m at 1 cm: 60,000 cells, +38 %
    CPU); the cap keeps each snapshot's cost the same at every region size.
    """
    if max_cells < 1:
        raise ValueError("max_cells must be at least 1")

    def cells(spacing: float) -> int:
        return (max(1, math.ceil(width_m / spacing)) * max(1, math.ceil(height_m / spacing)))

    if cells(spacing_m) <= max_cells:
        return float(spacing_m)
    # The area bound is a lower bound on the spacing; ceil() may still need a little more.
    spacing = max(spacing_m, math.sqrt(width_m * height_m / max_cells))
    while cells(spacing) > max_cells:
        spacing *= 1.01
    return float(spacing)


@dataclass(frozen=True)
class MapSnapshot:
    """A map's state at one model time, made by the run and handed to the writer.

    Attributes
    ----------
    map_id : str
    t_s : float
        Model time (seconds).
    origin_m : tuple of float
        The grid's lower-left corner ``(x, y)``, metres.
    cell_m : tuple of float
        One cell's size ``(dx, dy)``, metres.
    mean, std : ndarray of shape (ny, nx)
        The occupancy's mean and std on the grid (rows: y).
    outline : ndarray of shape (n, 2) or None
        The estimated outline (the ``outline_level`` curve around the most occupied blob),
        None while there is none.
    outline_level : float
    """

    map_id: str
    t_s: float
    origin_m: tuple[float, float]
    cell_m: tuple[float, float]
    mean: NDArray[np.float64]
    std: NDArray[np.float64]
    outline: NDArray[np.float64] | None
    outline_level: float

    @classmethod
    def of(cls, map_id: str, the_map: Map, t_s: float, spacing_m: float,
           outline_level: float, max_cells: int | None = None) -> MapSnapshot:
        """Query ``the_map`` on a grid of ``spacing_m`` over its region and trace its
        outline at ``outline_level``; with ``max_cells``, the grid is coarsened until it has
        at most that many cells (:func:`snapshot_spacing`)."""
        from hapticframe.geometry import main_outline, sample_grid

        region = the_map.region
        bounds = (region.x_min_m, region.x_max_m, region.y_min_m, region.y_max_m)
        if max_cells is not None:
            spacing_m = snapshot_spacing(bounds[1] - bounds[0], bounds[3] - bounds[2],
                                         spacing_m, max_cells)
        xs, ys, points = sample_grid(bounds, spacing_m)
        estimate = the_map.query(points)
        shape = (len(ys), len(xs))
        mean, std = estimate.mean.reshape(shape), estimate.std.reshape(shape)
        cell = ((bounds[1] - bounds[0]) / len(xs), (bounds[3] - bounds[2]) / len(ys))
        outline = main_outline(xs, ys, mean, outline_level)
        return cls(map_id, float(t_s), (bounds[0], bounds[2]), cell, mean, std,
                   None if outline is None else np.asarray(outline, dtype=np.float64),
                   float(outline_level))


class RecordingWriter(Protocol):
    """What a run writes its recording through, as it happens (``run.mcap``'s writer,
    :class:`~hapticframe.record._recording.RunRecording`, is one).

    The run layer calls these and nothing else; the writer decides the format.
    """

    #: True once :meth:`close` has run.
    closed: bool
    #: How many of the session's safety halts are written (the loop keeps it).
    halts_recorded: int
    #: Map snapshots per second of model time (0: none).
    snapshot_rate_hz: float

    @property
    def now_s(self) -> float:
        """The latest model time the writer has seen (seconds)."""
        ...

    def samples(self, kind: str, cid: str, batch: SampleBatch,
                units: Mapping[str, str] | None = None,
                rates_hz: Mapping[str, float] | None = None) -> None: ...

    def probabilities(self, cid: str, probs: ClassProbabilities) -> None: ...

    def located(self, sm_id: str, located: LocatedMeasurement) -> None: ...

    def observations(self, sm_id: str, obs: Observations, t_s: float) -> None: ...

    def robot_state(self, robot_id: str, state: RobotState, movement_index: int) -> None: ...

    def movement(self, result: MovementResult) -> None: ...

    def event(self, topic: str, schema: str, data: Mapping[str, Any],
              t_s: float | None = None) -> None: ...

    def later(self, topic: str, schema: str, data: Mapping[str, Any], t_s: float) -> None: ...

    def health(self, counters: Mapping[str, Mapping[str, int]]) -> None: ...

    def configure_snapshots(self, rate_hz: float) -> None: ...

    def snapshot_due(self, t_s: float | None = None) -> bool: ...

    def scene(self, scene: Scene | None) -> None: ...

    def map_snapshot(self, snapshot: MapSnapshot) -> None: ...

    def close(self) -> None:
        """Write what is left and the file's summary; idempotent. Raises
        :class:`~hapticframe.OutputError` when the file cannot be written."""
        ...


class RecordingOpener(Protocol):
    """Opens the run's recording in ``folder`` (the run's staging folder, whose files move
    into ``--out`` when the run ends) with the experiment's ``metadata``."""

    def __call__(self, folder: Path, metadata: Mapping[str, str]) -> RecordingWriter: ...
