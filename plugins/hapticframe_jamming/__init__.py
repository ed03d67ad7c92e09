"""Force/force-rate classifier of granular jamming and direct contact (thesis Figure 3.4).

Registers the classifier ``force-rate-jamming``. Importing this package is cheap; the
classifier and calibration code (scipy) load on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import ForceRateJammingConfig

__all__ = [
    "CLASSES",
    "DetectionReport",
    "ForceRateJammingClassifier",
    "ForceRateJammingConfig",
    "ForceRateTracker",
    "calibrate_thresholds",
    "evaluate_detection",
]

_LAZY = {
    "CLASSES": "._classifier",
    "ForceRateJammingClassifier": "._classifier",
    "ForceRateTracker": "._classifier",
    "DetectionReport": "._calibration",
    "calibrate_thresholds": "._calibration",
    "evaluate_detection": "._calibration",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
