"""Learned-zone sensor model: the classifier's reports over the cells around the plate,
learned from a lab's calibration recordings (issue 32 §2).

The implementation is imported on first use, so importing this package stays light.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import LearnedZoneConfig

__all__ = ["LearnedZone", "LearnedZoneConfig", "fit_counts"]

#: Public names that load on first use, and their modules.
_LAZY = {"LearnedZone": "._model", "fit_counts": "._model"}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
