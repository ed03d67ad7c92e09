"""Failure-zone kernel sensor model for haptic search in granular media.

A tactile sample (fingertip position, direction of motion, interaction-state probabilities)
is spread over the sector of granular material that fails ahead of the fingertip, with the
three-state kernel mixture of Jia (2022), Eqs. 3.2-3.4. The implementation is imported on
first use, so importing this package stays light.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import FailureZoneConfig

__all__ = [
    "FailureZoneAngleWarning",
    "FailureZoneConfig",
    "FailureZoneFit",
    "FailureZoneKernel",
    "fit_failure_zone",
]

#: Public names that load on first use, and their modules.
_LAZY = {
    "FailureZoneKernel": "._kernel",
    "FailureZoneAngleWarning": "._functional",
    "FailureZoneFit": "._calibration",
    "fit_failure_zone": "._calibration",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
