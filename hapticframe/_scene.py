"""The ``scene`` of an experiment: what a simulated world contains.

A scene is plain validated data (no behaviour beyond geometry helpers): the search region,
the granular material and the buried objects. Simulated robots and sensors read it from
their :class:`~hapticframe.kinds.BuildContext`; evaluation compares maps with it.

Every number is finite and physically bounded (:data:`MAX_COORDINATE_M`,
:data:`MIN_REGION_SIDE_M`, :data:`MAX_REGION_SIDE_M`, :data:`MIN_OBJECT_SIZE_M`); what
depends on several fields (an object inside the region, objects apart from each other) is
listed by :meth:`Scene.problems`, which ``validate`` reports, located.
"""

from __future__ import annotations

import functools
import math
from typing import Annotated, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from hapticframe.kinds._records import Region

__all__ = [
    "MAX_COORDINATE_M",
    "MAX_REGION_SIDE_M",
    "MIN_OBJECT_SIZE_M",
    "MIN_REGION_SIDE_M",
    "Circle",
    "Ellipse",
    "Material",
    "Polygon",
    "RegionConfig",
    "Scene",
    "SceneObject",
]

_FROZEN = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

#: The largest absolute coordinate of a region edge, object centre or vertex (metres): far
#: beyond any sandbox, small enough that no sum or product of coordinates overflows.
MAX_COORDINATE_M = 1000.0
#: A region's sides lie between these (metres): half a centimetre (the conformance kit
#: tries planners on a region smaller than any line spacing) and 20 m, twice the largest
#: bench region (10 x 10 m, tests/data/bhm/). A larger side is far more likely a region
#: written in centimetres (75 for 0.75) than a field raked by touch, so it is refused with
#: that question.
MIN_REGION_SIDE_M = 0.005
MAX_REGION_SIDE_M = 20.0
#: The smallest object size (a radius, a semi-axis; metres): smaller ones are below any
#: evaluation grid.
MIN_OBJECT_SIZE_M = 0.001
#: The most vertices a polygon may have.
MAX_POLYGON_VERTICES = 1000

_Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)]
_Size = Annotated[float, Field(ge=MIN_OBJECT_SIZE_M, le=MAX_REGION_SIDE_M / 2)]
_Offset = Annotated[float, Field(ge=-MAX_REGION_SIDE_M, le=MAX_REGION_SIDE_M)]
#: A one-line name: no control characters (NUL included), at most 200 characters.
NAME_PATTERN = r"^[^\x00-\x1f\x7f-\x9f]{1,200}$"


class RegionConfig(BaseModel):
    """An axis-aligned search region in metres."""

    model_config = _FROZEN
    x_min_m: _Coordinate = 0.0
    x_max_m: _Coordinate = Field(0.75, description="Default: the thesis's 75 cm search width.")
    y_min_m: _Coordinate = 0.0
    y_max_m: _Coordinate = Field(0.50, description="Default: the thesis's 50 cm search height.")

    @model_validator(mode="after")
    def _positive_size(self) -> RegionConfig:
        if not (self.x_max_m > self.x_min_m and self.y_max_m > self.y_min_m):
            raise ValueError("region needs x_max_m > x_min_m and y_max_m > y_min_m")
        width, height = self.x_max_m - self.x_min_m, self.y_max_m - self.y_min_m
        for axis, side in (("x", width), ("y", height)):
            if side > MAX_REGION_SIDE_M:
                raise ValueError(
                    f"the region is {side:.4g} m along {axis} ({axis}_min_m to {axis}_max_m), "
                    f"more than the {MAX_REGION_SIDE_M:g} m a side may be: did you mean "
                    f"centimetres? Every *_m value is in metres ({side:.4g} cm would be "
                    f"{side / 100:.4g} m)"
                )
            if side < MIN_REGION_SIDE_M:
                raise ValueError(
                    f"the region is {side:.4g} m along {axis}; a side must lie between "
                    f"{MIN_REGION_SIDE_M:g} m and {MAX_REGION_SIDE_M:g} m"
                )
        return self

    def to_region(self) -> Region:
        return Region(self.x_min_m, self.x_max_m, self.y_min_m, self.y_max_m)


class Material(BaseModel):
    """Granular material properties (defaults: the thesis's sand mixture, section 3.5.1)."""

    model_config = _FROZEN
    name: str = Field("sand-mixture", pattern=NAME_PATTERN)
    friction_angle_deg: float = Field(42.0, gt=0, lt=90, description="Internal friction angle φ.")
    dilation_angle_deg: float = Field(12.0, ge=0, lt=90, description="Dilation angle ψ.")
    bulk_density_kg_per_m3: float = Field(
        1800.0, gt=0, le=25_000, description="Up to 25,000 kg/m³ (denser than any element)."
    )


@functools.lru_cache(maxsize=64)
def _placement(
    center_m: tuple[float, float], orientation_deg: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The centre as an array and the map-to-local rotation of a shape, computed once per
    placement (a simulator tests points against a shape thousands of times per run)."""
    a = math.radians(orientation_deg)
    centre = np.asarray(center_m, dtype=np.float64)
    to_local = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    centre.setflags(write=False)
    to_local.setflags(write=False)
    return centre, to_local


class _Shape(BaseModel):
    model_config = _FROZEN
    center_m: tuple[_Coordinate, _Coordinate]
    orientation_deg: float = Field(
        0.0, ge=-360, le=360, description="Rotation about +z, counter-clockwise."
    )

    #: The config field that holds the shape's size (for located messages).
    size_field: ClassVar[str] = ""

    def bounds_m(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` of the placed shape, in the map frame."""
        points = self._extent_points()
        return (float(points[:, 0].min()), float(points[:, 0].max()),
                float(points[:, 1].min()), float(points[:, 1].max()))

    def _extent_points(self) -> NDArray[np.float64]:
        return self.outline(256)

    def min_width_m(self) -> float:
        """The shape's smallest width (over directions): what a step of the fingertip must
        stay below not to jump over it."""
        local = self._local_outline(256)
        t = np.linspace(0, np.pi, 90, endpoint=False)
        projections = local @ np.vstack([np.cos(t), np.sin(t)])
        return float((projections.max(axis=0) - projections.min(axis=0)).min())

    def reach_m(self) -> float:
        """The largest distance from the centroid to the outline (the radius of the circle
        about the centroid that holds the shape)."""
        return float(np.hypot(*(self.outline(256) - self.centroid_m).T).max())

    def outline(self, n: int = 256) -> NDArray[np.float64]:
        """``(n, 2)`` points on the outline in the map frame."""
        local = self._local_outline(n)
        a = math.radians(self.orientation_deg)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        points: NDArray[np.float64] = local @ rot.T + np.asarray(self.center_m)
        return points

    def _local_outline(self, n: int) -> NDArray[np.float64]:  # pragma: no cover - abstract
        raise NotImplementedError

    def contains(self, points_m: NDArray[np.float64]) -> NDArray[np.bool_]:
        """True for points inside the shape."""
        centre, to_local = _placement(self.center_m, self.orientation_deg)
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64)) - centre
        return self._local_contains(p @ to_local)

    def _local_contains(self, p: NDArray[np.float64]) -> NDArray[np.bool_]:  # pragma: no cover
        raise NotImplementedError

    @property
    def centroid_m(self) -> NDArray[np.float64]:
        return np.asarray(self.center_m, dtype=np.float64)


class Circle(_Shape):
    shape: Literal["circle"] = "circle"
    radius_m: _Size
    size_field: ClassVar[str] = "radius_m"

    def bounds_m(self) -> tuple[float, float, float, float]:
        (x, y), r = self.center_m, self.radius_m
        return (x - r, x + r, y - r, y + r)

    def min_width_m(self) -> float:
        return 2 * self.radius_m

    def reach_m(self) -> float:
        return self.radius_m

    def _local_outline(self, n: int) -> NDArray[np.float64]:
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return self.radius_m * np.column_stack([np.cos(t), np.sin(t)])

    def _local_contains(self, p: NDArray[np.float64]) -> NDArray[np.bool_]:
        return np.hypot(p[:, 0], p[:, 1]) <= self.radius_m


class Ellipse(_Shape):
    shape: Literal["ellipse"] = "ellipse"
    semi_axes_m: tuple[_Size, _Size] = Field(
        description="Semi-major (along local x), semi-minor."
    )
    size_field: ClassVar[str] = "semi_axes_m"

    def bounds_m(self) -> tuple[float, float, float, float]:
        (x, y), (a, b) = self.center_m, self.semi_axes_m
        t = math.radians(self.orientation_deg)
        half_x = math.hypot(a * math.cos(t), b * math.sin(t))
        half_y = math.hypot(a * math.sin(t), b * math.cos(t))
        return (x - half_x, x + half_x, y - half_y, y + half_y)

    def min_width_m(self) -> float:
        return 2 * min(self.semi_axes_m)

    def reach_m(self) -> float:
        return max(self.semi_axes_m)

    def _local_outline(self, n: int) -> NDArray[np.float64]:
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        a, b = self.semi_axes_m
        return np.column_stack([a * np.cos(t), b * np.sin(t)])

    def _local_contains(self, p: NDArray[np.float64]) -> NDArray[np.bool_]:
        a, b = self.semi_axes_m
        return (p[:, 0] / a) ** 2 + (p[:, 1] / b) ** 2 <= 1.0


class Polygon(_Shape):
    """A simple polygon given by vertices relative to ``center_m`` (before rotation)."""

    shape: Literal["polygon"] = "polygon"
    center_m: tuple[_Coordinate, _Coordinate] = (0.0, 0.0)
    vertices_m: list[tuple[_Offset, _Offset]] = Field(
        min_length=3, max_length=MAX_POLYGON_VERTICES
    )
    size_field: ClassVar[str] = "vertices_m"

    @model_validator(mode="after")
    def _has_area(self) -> Polygon:
        v = np.asarray(self.vertices_m, dtype=np.float64)
        area = abs(float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])))
        if area / 2 < MIN_OBJECT_SIZE_M**2:
            raise ValueError(
                f"the polygon's area is {area / 2:.3g} m²; it needs at least "
                f"{MIN_OBJECT_SIZE_M**2:g} m² (vertices in order around a real outline)"
            )
        return self

    def _extent_points(self) -> NDArray[np.float64]:
        a = math.radians(self.orientation_deg)
        rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
        placed: NDArray[np.float64] = (
            np.asarray(self.vertices_m, dtype=np.float64) @ rot.T + np.asarray(self.center_m)
        )
        return placed

    def _local_outline(self, n: int) -> NDArray[np.float64]:
        v = np.asarray(self.vertices_m, dtype=np.float64)
        closed = np.vstack([v, v[:1]])
        seg = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        t = np.linspace(0, s[-1], n, endpoint=False)
        return np.column_stack([np.interp(t, s, closed[:, 0]), np.interp(t, s, closed[:, 1])])

    def _local_contains(self, p: NDArray[np.float64]) -> NDArray[np.bool_]:
        v = np.asarray(self.vertices_m, dtype=np.float64)
        inside = np.zeros(len(p), dtype=bool)
        x, y = p[:, 0], p[:, 1]
        for (x0, y0), (x1, y1) in zip(v, np.roll(v, -1, axis=0), strict=True):
            crosses = (y0 > y) != (y1 > y)
            with np.errstate(divide="ignore", invalid="ignore"):
                x_at = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
            inside ^= crosses & (x < x_at)
        return inside

    @property
    def centroid_m(self) -> NDArray[np.float64]:
        v = self.outline(4 * len(self.vertices_m))
        x, y = v[:, 0], v[:, 1]
        cross = x * np.roll(y, -1) - np.roll(x, -1) * y
        area = cross.sum() / 2
        cx = ((x + np.roll(x, -1)) * cross).sum() / (6 * area)
        cy = ((y + np.roll(y, -1)) * cross).sum() / (6 * area)
        return np.array([cx, cy])


SceneObject = Annotated[Circle | Ellipse | Polygon, Field(discriminator="shape")]


class Scene(BaseModel):
    """What a simulated sandbox contains."""

    model_config = _FROZEN
    region: RegionConfig = RegionConfig()
    material: Material = Material()
    objects: list[SceneObject] = Field(default_factory=list)

    def problems(self) -> list[tuple[str, str]]:
        """What is impossible about the scene as a whole: ``(path, message)`` pairs, paths
        relative to the scene (``"objects[1].center_m"``). Empty when the scene is sound.

        Each object must fit in the region and lie inside it, and no two may overlap (each
        outline sampled at 256 points, so an overlap thinner than a 256th of the smaller
        outline may pass).
        """
        out: list[tuple[str, str]] = []
        r = self.region
        width, height = r.x_max_m - r.x_min_m, r.y_max_m - r.y_min_m
        boxes = []
        for i, obj in enumerate(self.objects):
            x0, x1, y0, y1 = box = obj.bounds_m()
            boxes.append(box)
            what = f"the {obj.shape} at ({obj.center_m[0]:.4g}, {obj.center_m[1]:.4g}) m"
            if x1 - x0 >= width or y1 - y0 >= height:
                out.append((f"objects[{i}].{obj.size_field}", (
                    f"{what} spans {x1 - x0:.4g} x {y1 - y0:.4g} m, not smaller than the "
                    f"region ({width:.4g} x {height:.4g} m): make it smaller or the region "
                    "larger"
                )))
            elif x0 < r.x_min_m or x1 > r.x_max_m or y0 < r.y_min_m or y1 > r.y_max_m:
                out.append((f"objects[{i}].center_m", (
                    f"{what} reaches x {x0:.4g}...{x1:.4g} m, y {y0:.4g}...{y1:.4g} m, "
                    f"outside the region (x {r.x_min_m:g}...{r.x_max_m:g} m, y "
                    f"{r.y_min_m:g}...{r.y_max_m:g} m): move it inside or enlarge "
                    "scene.region"
                )))
        for j, b in enumerate(self.objects):
            for i in range(j):
                a = self.objects[i]
                ba, bb = boxes[i], boxes[j]
                if ba[1] < bb[0] or bb[1] < ba[0] or ba[3] < bb[2] or bb[3] < ba[2]:
                    continue  # bounding boxes apart: no overlap
                if a.contains(b.outline(256)).any() or b.contains(a.outline(256)).any() or (
                    a.contains(b.centroid_m).any()
                ):
                    out.append((f"objects[{j}].center_m", (
                        f"the {b.shape} at ({b.center_m[0]:.4g}, {b.center_m[1]:.4g}) m "
                        f"overlaps objects[{i}] (the {a.shape} at ({a.center_m[0]:.4g}, "
                        f"{a.center_m[1]:.4g}) m): buried objects must be apart"
                    )))
        return out

    def occupied(self, points_m: NDArray[np.float64]) -> NDArray[np.bool_]:
        """True for points inside any buried object."""
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        out = np.zeros(len(p), dtype=bool)
        for obj in self.objects:
            out |= obj.contains(p)
        return out
