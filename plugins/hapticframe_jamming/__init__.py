"""Force/force-rate classifier of granular jamming and direct contact (thesis Figure 3.4).

Registers the classifiers ``force-rate-jamming`` and ``drag-ratio-jamming`` (force in
units of the movement's own free drag). Importing this package is cheap; the
classifier and calibration code (scipy) load on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import ForceRateJammingConfig
from ._drag_config import DragRatioJammingConfig

__all__ = [
    "CLASSES",
    "DetectionReport",
    "DragRatioJammingClassifier",
    "DragRatioJammingConfig",
    "DragTrace",
    "DragTracker",
    "ForceRateJammingClassifier",
    "ForceRateJammingConfig",
    "ForceRateTracker",
    "and_rule_margin",
    "calibrate_drag_ratio",
    "calibrate_thresholds",
    "evaluate_detection",
    "operating_points",
]

_LAZY = {
    "CLASSES": "._classifier",
    "ForceRateJammingClassifier": "._classifier",
    "ForceRateTracker": "._classifier",
    "and_rule_margin": "._functional",
    "DetectionReport": "._calibration",
    "calibrate_thresholds": "._calibration",
    "evaluate_detection": "._calibration",
    "DragRatioJammingClassifier": "._drag_classifier",
    "DragTrace": "._drag_classifier",
    "DragTracker": "._drag_functional",
    "calibrate_drag_ratio": "._drag_calibration",
    "operating_points": "._drag_calibration",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
