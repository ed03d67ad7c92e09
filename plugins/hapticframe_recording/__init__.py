"""Replaying recorded runs: labelled recordings for ``hapticframe train``.

Registers the sensor ``trace-recording``, which replays one sensor of a previous run's
``trace.npz`` as a finite source, split into one trial per exploratory movement, with labels
from a ground-truth file (the ``ground_truth.npz`` a sandbox run writes) or a lab's own
annotations. Importing this package is cheap; the replay code loads on first attribute access.
"""

from __future__ import annotations

import importlib
from typing import Any

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


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
