"""SynTouch BioTac fingertip: frame layout, SPI wire decoding, an emulator, replay, and the sensor.

Registers the sensor ``biotac``; the synthetic granular-media generator lives in ``_synthetic``.
A real SPI adapter is a separate package that registers a backend factory by name in the
``hapticframe.biotac_spi`` entry-point group (see ``_backends``). Importing this package is
cheap; the implementation modules load on first attribute access.
"""

from __future__ import annotations

import importlib
from typing import Any

from ._config import BioTacSensorConfig

__all__ = [
    "BioTacFrames",
    "BioTacSensor",
    "BioTacSensorConfig",
    "EmulatedBioTac",
    "FaultPlan",
    "FrameLayout",
    "Recording",
    "ReplayFormatError",
    "SpiBatchBackend",
    "Trial",
    "TrialSpec",
    "WordStreamDecoder",
    "encode_frames",
    "generate_trial",
    "load_csv",
    "load_npz",
    "load_recording",
    "robustness_specs",
    "save_npz",
    "schedule_for",
    "training_specs",
]

_LAZY = {
    "BioTacFrames": "._frame",
    "FrameLayout": "._frame",
    "BioTacSensor": "._sensor",
    "EmulatedBioTac": "._emulator",
    "FaultPlan": "._emulator",
    "SpiBatchBackend": "._emulator",
    "WordStreamDecoder": "._wire",
    "encode_frames": "._wire",
    "schedule_for": "._wire",
    "Recording": "._replay",
    "ReplayFormatError": "._replay",
    "load_csv": "._replay",
    "load_npz": "._replay",
    "load_recording": "._replay",
    "save_npz": "._replay",
    # the synthetic granular-media generator (its own module, numpy-heavy)
    "Trial": "._synthetic",
    "TrialSpec": "._synthetic",
    "generate_trial": "._synthetic",
    "training_specs": "._synthetic",
    "robustness_specs": "._synthetic",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
