"""Random placements of the buried objects of Table 3.2 (Jia 2022, section 3.5.2.1).

Two shapes are buried at random locations and orientations in the 75 x 50 cm search area:
a circle of 8 cm diameter and an ellipse with 9 cm and 5 cm axes. Every object lies fully
inside the region. Beyond the thesis (issue 19): two concave polygons of the circle's area
(``l-shape``, ``star``) and scenes of several objects (``two-objects``: a circle and an
ellipse; ``three-objects``: a circle, an ellipse and an L-shape), their outlines at least
``gap_m`` apart; and (issue 32) a 7 x 5 cm ``box``. Placements are drawn per trial, circle
then ellipse, from one seeded generator, so the first ``k`` trials of a run with more
trials are the same ``k`` trials: a quick run is a prefix of the full one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "BOX_HALF_EXTENTS_M",
    "CIRCLE_RADIUS_M",
    "ELLIPSE_SEMI_AXES_M",
    "L_SHAPE_VERTICES_M",
    "MULTI_SCENES",
    "POLYGON_SHAPES",
    "SCENE_GAP_M",
    "SCENE_SETS",
    "SHAPES",
    "STAR_VERTICES_M",
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
#: A 7 x 5 cm box (the ellipse's area, corners the kernels never saw): the shape no setting
#: was chosen on in ``bench search-physics`` (issue 32 §5).
BOX_HALF_EXTENTS_M = (0.035, 0.025)


def _about_centroid(vertices: list[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    """The vertices shifted so that the polygon's area centroid is the origin."""
    v = np.asarray(vertices, dtype=np.float64)
    x, y = v[:, 0], v[:, 1]
    cross = x * np.roll(y, -1) - np.roll(x, -1) * y
    area = cross.sum() / 2
    cx = ((x + np.roll(x, -1)) * cross).sum() / (6 * area)
    cy = ((y + np.roll(y, -1)) * cross).sum() / (6 * area)
    return tuple((float(a - cx), float(b - cy)) for a, b in v)


#: An L of three 4.09 cm squares (8.2 x 8.2 cm, a 4.1 cm notch): the 8 cm circle's area.
_L_UNIT_M = math.sqrt(math.pi * CIRCLE_RADIUS_M**2 / 3)
L_SHAPE_VERTICES_M = _about_centroid([
    (0.0, 0.0), (2 * _L_UNIT_M, 0.0), (2 * _L_UNIT_M, _L_UNIT_M), (_L_UNIT_M, _L_UNIT_M),
    (_L_UNIT_M, 2 * _L_UNIT_M), (0.0, 2 * _L_UNIT_M),
])
#: A 5-point star, inner radius half the outer (arms 2.9 cm wide at their base), of the
#: circle's area: outer radius sqrt(area / (5 sin 36° / 2)).
_STAR_OUTER_M = math.sqrt(math.pi * CIRCLE_RADIUS_M**2 / (2.5 * math.sin(math.radians(36))))
STAR_VERTICES_M = tuple(
    (float(r * math.cos(math.radians(90 + 36 * k))), float(r * math.sin(math.radians(90 + 36 * k))))
    for k, r in ((k, _STAR_OUTER_M if k % 2 == 0 else _STAR_OUTER_M / 2) for k in range(10))
)
#: Concave polygons of comparable area (issue 19 §4), each its own row.
POLYGON_SHAPES = ("l-shape", "star")
#: Scenes of several objects (issue 19 §3) and the shapes each buries.
MULTI_SCENES: dict[str, tuple[str, ...]] = {
    "two-objects": ("circle", "ellipse"),
    "three-objects": ("circle", "ellipse", "l-shape"),
}
#: Scene sets by name, as ``bench search-scenes`` runs them.
SCENE_SETS: dict[str, tuple[str, ...]] = {
    "polygons": POLYGON_SHAPES,
    "multi": tuple(MULTI_SCENES),
}
#: Least distance between the outlines of two objects of one scene.
SCENE_GAP_M = 0.10
_VERTICES = {
    "l-shape": L_SHAPE_VERTICES_M,
    "star": STAR_VERTICES_M,
    "box": tuple((sx * BOX_HALF_EXTENTS_M[0], sy * BOX_HALF_EXTENTS_M[1])
                 for sx, sy in ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))),
}


@dataclass(frozen=True)
class Placement:
    """One buried object: its shape, centre and orientation.

    Parameters
    ----------
    shape : str
        ``"circle"``, ``"ellipse"``, a polygon (``"l-shape"``, ``"star"``, ``"box"``) or a
        multi-object scene (:data:`MULTI_SCENES`).
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
    parts: tuple[Placement, ...] = ()

    def scene_objects(self) -> list[dict[str, Any]]:
        """Every object of the placement as scene data (one, or a multi-object scene's)."""
        if self.parts:
            return [part.scene_object() for part in self.parts]
        return [self.scene_object()]

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
        if self.shape in _VERTICES:
            return {**common, "shape": "polygon",
                    "vertices_m": [list(v) for v in _VERTICES[self.shape]]}
        raise ValueError(f"unknown shape {self.shape!r}; expected one of {SHAPES}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record of the placement (with its ``parts`` for a multi-object scene)."""
        out: dict[str, Any] = {
            "shape": self.shape,
            "index": self.index,
            "center_m": [self.center_m[0], self.center_m[1]],
            "orientation_deg": self.orientation_deg,
        }
        if self.parts:
            out["parts"] = [part.to_dict() for part in self.parts]
        return out


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
    if shape in _VERTICES:
        t = math.radians(orientation_deg)
        v = np.asarray(_VERTICES[shape], dtype=np.float64)
        x = v[:, 0] * math.cos(t) - v[:, 1] * math.sin(t)
        y = v[:, 0] * math.sin(t) + v[:, 1] * math.cos(t)
        return float(np.abs(x).max()), float(np.abs(y).max())
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


def _outline(placement: Placement) -> np.ndarray:
    """The placed object's outline, 128 points (for the gap between objects)."""
    from hapticframe import Scene

    scene = Scene.model_validate({"objects": [placement.scene_object()],
                                  "region": {"x_min_m": -10, "x_max_m": 10,
                                             "y_min_m": -10, "y_max_m": 10}})
    return np.asarray(scene.objects[0].outline(128), dtype=np.float64)


def _draw_scene(
    rng: np.random.Generator, scene: str, index: int, bounds: tuple[float, float, float, float],
    gap_m: float, attempts: int = 1000,
) -> Placement:
    """A multi-object scene: each object drawn in turn until its outline lies ``gap_m``
    from those before (and neither centre lies inside the other)."""
    parts: list[Placement] = []
    outlines: list[np.ndarray] = []
    for shape in MULTI_SCENES[scene]:
        for _ in range(attempts):
            candidate = _draw_one(rng, shape, index, bounds)
            outline = _outline(candidate)
            if all(float(np.min(np.hypot(*(outline[:, None, :] - other[None, :, :]).T)))
                   >= gap_m for other in outlines):
                parts.append(candidate)
                outlines.append(outline)
                break
        else:
            raise ValueError(f"no room for the {scene} scene's {shape} {gap_m} m from the "
                             f"others in {bounds}: lower the gap")
    centre = np.mean([p.center_m for p in parts], axis=0)
    return Placement(scene, index, (float(centre[0]), float(centre[1])), 0.0, tuple(parts))


def draw_placements(
    rng: np.random.Generator,
    trials: int,
    bounds_m: tuple[float, float, float, float] = (0.0, 0.75, 0.0, 0.50),
    shapes: tuple[str, ...] = SHAPES,
    gap_m: float = SCENE_GAP_M,
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
        Shapes (or multi-object scenes, :data:`MULTI_SCENES`) to place; each trial draws
        them in this order.
    gap_m : float
        Least distance between two objects' outlines in a multi-object scene.

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
            if shape in MULTI_SCENES:
                out[shape].append(_draw_scene(rng, shape, index, bounds_m, gap_m))
            else:
                out[shape].append(_draw_one(rng, shape, index, bounds_m))
    return out
