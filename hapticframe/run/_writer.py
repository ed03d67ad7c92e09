"""What a run records through: the recording writer's protocol (dependency inversion).

The run layer writes its recording through a :class:`RecordingWriter` that the caller
opens with a :class:`RecordingOpener` (``run.mcap``'s writer lives in
:mod:`hapticframe.record`, above this layer, and is never imported here).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from hapticframe._defaults import OUTLINE_LEVEL

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

__all__ = ["RecordingOpener", "RecordingWriter"]


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

    def configure_snapshots(self, rate_hz: float, spacing_m: float,
                            outline_level: float = OUTLINE_LEVEL) -> None: ...

    def snapshot_due(self, t_s: float | None = None) -> bool: ...

    def scene(self, scene: Scene | None) -> None: ...

    def map_snapshot(self, map_id: str, the_map: Map, t_s: float) -> None: ...

    def close(self) -> None:
        """Write what is left and the file's summary; idempotent. Raises
        :class:`~hapticframe.OutputError` when the file cannot be written."""
        ...


class RecordingOpener(Protocol):
    """Opens the run's recording in ``folder`` (the run's staging folder, whose files move
    into ``--out`` when the run ends) with the experiment's ``metadata``."""

    def __call__(self, folder: Path, metadata: Mapping[str, str]) -> RecordingWriter: ...
