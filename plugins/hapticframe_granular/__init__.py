"""Granular mechanics shared by the bundled plugins: the failure zone ahead of a raking plate.

One home for the Arthur angle, the rupture distance and the side-crescent angle of the
dissertation's failure-zone model (Jia 2022, section 3.4.3.1, Figure 3.2, Table 3.1), used by
the ``sandbox`` simulator and the ``failure-zone`` sensor model alike. A library, not a
plugin: it registers nothing. SI units (metres, radians) in and out; see
:mod:`hapticframe_granular._mechanics` for the shape and domain policy every function follows.
"""

from __future__ import annotations

from ._mechanics import (
    SIDE_CRESCENT_ANGLE_CAP,
    arthur_angle,
    rupture_distance,
    side_crescent_angle,
    side_crescent_angle_analytic,
)

__all__ = [
    "SIDE_CRESCENT_ANGLE_CAP",
    "arthur_angle",
    "rupture_distance",
    "side_crescent_angle",
    "side_crescent_angle_analytic",
]
