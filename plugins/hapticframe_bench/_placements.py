"""Random placements of the buried objects of Table 3.2 (Jia 2022, section 3.5.2.1).

Two shapes are buried at random locations and orientations in the 75 x 50 cm search area:
a circle of 8 cm diameter and an ellipse with 9 cm and 5 cm axes. Every object lies fully
inside the region. Placements are drawn per trial, circle then ellipse, from one seeded
generator, so the first ``k`` trials of a run with more trials are the same ``k`` trials:
a quick run is a prefix of the full one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "CIRCLE_RADIUS_M",
    "ELLIPSE_SEMI_AXES_M",
    "SHAPES",
    "Placement",
    "bounding_half_extents",
    "draw_placements",
]

#: Circle of 8 cm diameter.
CIRCLE_RADIUS_M = 0.04
#: Ellipse with a 9 cm major and a 5 cm minor axis.
ELLIPSE_SEMI_AXES_M = (0.045, 0.025)
#: The shapes of Table 3.2, in the order of its rows.
SHAPES = ("circle", "ellipse")


@dataclass(frozen=True)
class Placement:
    """One buried object: its shape, centre and orientation.

    Parameters
    ----------
    shape : str
        ``"circle"`` or ``"ellipse"``.
    index : int
        0-based trial number.
    center_m : tuple of float
        Centre (= centroid) in the map frame.
    orientation_deg : float
        Rotation about +z, counter-clockwise, in [0, 180).
    """

    shape: str
    index: int
    center_m: tuple[float, float]
    orientation_deg: float

    def scene_object(self) -> dict[str, Any]:
        """The object as scene data for an experiment's ``scene.objects``."""
        common = {
            "shape": self.shape,
            "center_m": [self.center_m[0], self.center_m[1]],
            "orientation_deg": self.orientation_deg,
        }
        if self.shape == "circle":
            return {**common, "radius_m": CIRCLE_RADIUS_M}
        if self.shape == "ellipse":
            return {**common, "semi_axes_m": list(ELLIPSE_SEMI_AXES_M)}
        raise ValueError(f"unknown shape {self.shape!r}; expected one of {SHAPES}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record of the placement."""
        return {
            "shape": self.shape,
            "index": self.index,
            "center_m": [self.center_m[0], self.center_m[1]],
            "orientation_deg": self.orientation_deg,
        }


def bounding_half_extents(shape: str, orientation_deg: float) -> tuple[float, float]:
    """Half width and half height of the axis-aligned box around a rotated object.

    For an ellipse with semi-axes ``a, b`` rotated by ``theta`` the box's half sizes are
    ``sqrt(a² cos² + b² sin²)`` and ``sqrt(a² sin² + b² cos²)``.
    """
    if shape == "circle":
        return CIRCLE_RADIUS_M, CIRCLE_RADIUS_M
    if shape == "ellipse":
        a, b = ELLIPSE_SEMI_AXES_M
        t = math.radians(orientation_deg)
        c2, s2 = math.cos(t) ** 2, math.sin(t) ** 2
        return math.sqrt(a * a * c2 + b * b * s2), math.sqrt(a * a * s2 + b * b * c2)
    raise ValueError(f"unknown shape {shape!r}; expected one of {SHAPES}")


def _draw_one(
    rng: np.random.Generator, shape: str, index: int, bounds: tuple[float, float, float, float]
) -> Placement:
    x_min, x_max, y_min, y_max = bounds
    # Orientation first: it fixes how much room the object needs from each edge.
    orientation = float(rng.uniform(0.0, 180.0))
    half_w, half_h = bounding_half_extents(shape, orientation)
    if x_max - x_min < 2 * half_w or y_max - y_min < 2 * half_h:
        raise ValueError(f"a {shape} does not fit in the region {bounds}")
    x = float(rng.uniform(x_min + half_w, x_max - half_w))
    y = float(rng.uniform(y_min + half_h, y_max - half_h))
    return Placement(shape, index, (x, y), orientation)


def draw_placements(
    rng: np.random.Generator,
    trials: int,
    bounds_m: tuple[float, float, float, float] = (0.0, 0.75, 0.0, 0.50),
    shapes: tuple[str, ...] = SHAPES,
) -> dict[str, list[Placement]]:
    """``trials`` random placements of each shape, fully inside ``bounds_m``.

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness (``numpy.random.default_rng(seed)``).
    trials : int
        Placements per shape (at least 1).
    bounds_m : tuple of float
        ``(x_min, x_max, y_min, y_max)`` of the search region.
    shapes : tuple of str
        Shapes to place; each trial draws them in this order.

    Returns
    -------
    dict of str to list of Placement
        One list per shape, ``trials`` long.
    """
    if not isinstance(trials, int) or isinstance(trials, bool) or trials < 1:
        raise ValueError(f"trials must be a positive int, got {trials!r}")
    if not all(math.isfinite(b) for b in bounds_m):
        raise ValueError(f"bounds_m must be finite, got {bounds_m}")
    out: dict[str, list[Placement]] = {shape: [] for shape in shapes}
    for index in range(trials):
        for shape in shapes:
            out[shape].append(_draw_one(rng, shape, index, bounds_m))
    return out
