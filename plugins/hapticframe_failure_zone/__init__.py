"""Failure-zone kernel sensor model for haptic search in granular media.

A tactile sample (fingertip position, direction of motion, interaction-state probabilities)
is spread over the sector of granular material that fails ahead of the fingertip, with the
three-state kernel mixture of Jia (2022), Eqs. 3.2-3.4. The implementation is imported on
first use, so importing this package stays light.
"""

from __future__ import annotations

from typing import Any

from ._config import FailureZoneConfig

__all__ = ["FailureZoneAngleWarning", "FailureZoneConfig", "FailureZoneKernel"]


def __getattr__(name: str) -> Any:
    if name == "FailureZoneKernel":
        from ._kernel import FailureZoneKernel

        return FailureZoneKernel
    if name == "FailureZoneAngleWarning":
        from ._functional import FailureZoneAngleWarning

        return FailureZoneAngleWarning
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
