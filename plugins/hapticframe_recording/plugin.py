"""Registration of the ``trace-recording`` and ``recording`` sensors (import-light)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import SensorSpec, hookimpl

from ._config import TraceRecordingConfig
from ._mcap_config import McapRecordingConfig

__all__ = ["SPECS", "hapticframe_sensors"]

#: The specs this package registers (for the conformance kit and tests).
SPECS = (
    SensorSpec(
        name="trace-recording",
        summary="Replays one sensor a previous run recorded in its trace.npz, one trial per "
        "exploratory movement, with optional labels (e.g. the sandbox's ground truth).",
        config=TraceRecordingConfig,
        factory="hapticframe_recording._sensor:TraceRecordingSensor",
        capabilities=frozenset({"finite"}),
        inputs=(),
        # The built-in recording needs no files; a lab's kit run can point at its own trace.
        check_config={"demo": True, "samples_per_read": 7},
    ),
    SensorSpec(
        name="recording",
        summary="Feeds one sensor channel a run recorded in its run.mcap (or an imported "
        "bag) into a pipeline again, with its recorded timestamps, units and rates.",
        config=McapRecordingConfig,
        factory="hapticframe_recording._mcap:RecordingSensor",
        capabilities=frozenset({"finite"}),
        inputs=(),
        # The built-in recording needs no file; a lab's kit run can point at its own.
        check_config={"demo": True},
    ),
)


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield from SPECS
