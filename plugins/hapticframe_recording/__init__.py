"""Replaying recorded runs: labelled recordings for ``hapticframe train``.

Registers the sensor ``trace-recording``, which replays one sensor of a previous run's
``trace.npz`` as a finite source, split into one trial per exploratory movement, with labels
from a ground-truth file (the ``ground_truth.npz`` a sandbox run writes) or a lab's own
annotations. Importing this package is cheap; the replay code loads on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import TraceRecordingConfig
from ._mcap_config import McapRecordingConfig

__all__ = [
    "GROUND_TRUTH_FILE",
    "McapRecordingConfig",
    "RecordingSensor",
    "TRACE_FILE",
    "Recording",
    "RecordingError",
    "TraceRecordingConfig",
    "TraceRecordingSensor",
    "demo_trace",
    "load_labels",
    "load_recording",
    "read_trace",
    "recording_from_arrays",
]

_LAZY = {
    "GROUND_TRUTH_FILE": "._replay",
    "TRACE_FILE": "._replay",
    "Recording": "._replay",
    "RecordingError": "._replay",
    "demo_trace": "._replay",
    "load_labels": "._replay",
    "load_recording": "._replay",
    "read_trace": "._replay",
    "recording_from_arrays": "._replay",
    "TraceRecordingSensor": "._sensor",
    "RecordingSensor": "._mcap",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
