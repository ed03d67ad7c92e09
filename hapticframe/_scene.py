"""The ``scene`` of an experiment: what a simulated world contains.

A scene is plain validated data (no behaviour beyond geometry helpers): the search region,
the granular material and the buried objects. Simulated robots and sensors read it from
their :class:`~hapticframe.kinds.BuildContext`; evaluation compares maps with it.
"""

from __future__ import annotations

import functools
import math
from typing import Annotated, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import BaseModel, ConfigDict, Field, model_validator

from .kinds._records import Region

__all__ = ["Circle", "Ellipse", "Material", "Polygon", "RegionConfig", "Scene", "SceneObject"]

_FROZEN = ConfigDict(extra="forbid", frozen=True)


class RegionConfig(BaseModel):
    """An axis-aligned search region in metres."""

    model_config = _FROZEN
    x_min_m: float = 0.0
    x_max_m: float = Field(0.75, description="Default: the thesis's 75 cm search width.")
    y_min_m: float = 0.0
    y_max_m: float = Field(0.50, description="Default: the thesis's 50 cm search height.")

    @model_validator(mode="after")
    def _positive_size(self) -> RegionConfig:
        if not (self.x_max_m > self.x_min_m and self.y_max_m > self.y_min_m):
            raise ValueError("region needs x_max_m > x_min_m and y_max_m > y_min_m")
        return self

    def to_region(self) -> Region:
        return Region(self.x_min_m, self.x_max_m, self.y_min_m, self.y_max_m)


class Material(BaseModel):
    """Granular material properties (defaults: the thesis's sand mixture, section 3.5.1)."""

    model_config = _FROZEN
    name: str = "sand-mixture"
    friction_angle_deg: float = Field(42.0, gt=0, lt=90, description="Internal friction angle φ.")
    dilation_angle_deg: float = Field(12.0, ge=0, lt=90, description="Dilation angle ψ.")
    bulk_density_kg_per_m3: float = Field(1800.0, gt=0)


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
    center_m: tuple[float, float]
    orientation_deg: float = Field(0.0, description="Rotation about +z, counter-clockwise.")

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
    radius_m: float = Field(gt=0)

    def _local_outline(self, n: int) -> NDArray[np.float64]:
        t = np.linspace(0, 2 * np.pi, n, endpoint=False)
        return self.radius_m * np.column_stack([np.cos(t), np.sin(t)])

    def _local_contains(self, p: NDArray[np.float64]) -> NDArray[np.bool_]:
        return np.hypot(p[:, 0], p[:, 1]) <= self.radius_m


class Ellipse(_Shape):
    shape: Literal["ellipse"] = "ellipse"
    semi_axes_m: tuple[float, float] = Field(description="Semi-major (along local x), semi-minor.")

    @model_validator(mode="after")
    def _positive_axes(self) -> Ellipse:
        if min(self.semi_axes_m) <= 0:
            raise ValueError("semi_axes_m must be positive")
        return self

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
    center_m: tuple[float, float] = (0.0, 0.0)
    vertices_m: list[tuple[float, float]] = Field(min_length=3)

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

    def occupied(self, points_m: NDArray[np.float64]) -> NDArray[np.bool_]:
        """True for points inside any buried object."""
        p = np.atleast_2d(np.asarray(points_m, dtype=np.float64))
        out = np.zeros(len(p), dtype=bool)
        for obj in self.objects:
            out |= obj.contains(p)
        return out
