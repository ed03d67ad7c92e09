"""The response library: engine runs on a small grid, stored as plain arrays, interpolated.

A library holds, for each raking depth ``d`` of a grid, the free-sand drag of a plate against
its travel (the start-up included), and, for each (depth, object radius ``R``, normalised
lateral offset ``u = |e| / (R + a)``, ``a`` the plate's half-width), the force on the plate
as a ratio of the free drag at the same travel, against ``s``: the plate front's position
relative to the object's leading point along the path (negative ahead of it, 0 at its
leading point). The y ratio is signed for an object on the +y side of the plate.

A library may also hold *shape tables* (issue 32, §4): engine runs towards elliptic and
rectangular prisms at yaws ψ of 0–90° to the raking direction, stored per (depth, shape,
ψ, signed offset u, s) with each shape's outline (about its centre, at ψ = 0) so that a
world can tell which scene objects a table describes (:meth:`ResponseLibrary.match_shape`).
Here u is signed: positive with the object on the plate's +y (left) side, and normalised by
the object's half-extent across the heading at that yaw. Other yaws follow from the
shapes' mirror symmetry (:meth:`ResponseLibrary.shape_ratio`). A library without them
(older files) has zero shapes.

Everything in a library file is a float64 or int64 array (``numpy.load`` without pickles);
``load_library`` checks shapes and finiteness and says which array is wrong. Interpolation
is multilinear over (depth, R, u, s) and clamps at the grid's edges; free drag below the
shallowest depth follows the power law fitted over the grid (``drag_exponent``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from hapticframe.bounded_io import BoundedReadError, open_regular, read_npz

__all__ = ["ResponseLibrary", "fit_power_law", "load_library", "material_parameters",
           "save_library", "support_function"]

#: Bytes of arrays a library file may declare (ours hold a few hundred kB).
MAX_LIBRARY_BYTES = 256 * 1024**2
#: The arrays a library file holds, with their dimensions (names of the axes).
_ARRAYS = {
    "depths_m": ("depth",),
    "radii_m": ("radius",),
    "offsets_u": ("offset",),
    "s_m": ("s",),
    "travel_m": ("travel",),
    "free_drag_n": ("depth", "travel"),
    "ratio_x": ("depth", "radius", "offset", "s"),
    "ratio_y": ("depth", "radius", "offset", "s"),
    "settings": ("setting",),
    "shape_outlines_m": ("shape", "outline_point", "xy"),
    "shape_yaws_deg": ("yaw",),
    "shape_offsets_u": ("shape_offset",),
    "shape_ratio_x": ("depth", "shape", "yaw", "shape_offset", "s"),
    "shape_ratio_y": ("depth", "shape", "yaw", "shape_offset", "s"),
}
#: Arrays an older library file may lack (then it holds no shape tables).
_OPTIONAL = frozenset(name for name in _ARRAYS if name.startswith("shape_"))
#: Directions of the support function that matches outlines (5° apart; a quarter turn is
#: a whole number of them).
_SUPPORT_DIRECTIONS = 72
#: Outlines match when their support functions differ by at most this (m) or this
#: fraction of the entry's size, whichever is larger.
_MATCH_TOLERANCE_M = 0.003
_MATCH_TOLERANCE_FRACTION = 0.05


def support_function(outline_m: NDArray[np.float64]) -> NDArray[np.float64]:
    """The outline's support function (its extent along each of 72 directions 5° apart,
    measured from the centre of its bounding box): two shapes with equal support functions
    have the same convex hull."""
    points = np.asarray(outline_m, dtype=np.float64)
    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    t = np.arange(_SUPPORT_DIRECTIONS) * (2 * np.pi / _SUPPORT_DIRECTIONS)
    return np.asarray(((points - centre) @ np.vstack([np.cos(t), np.sin(t)])).max(axis=0),
                      dtype=np.float64)


def _empty_shape_arrays(depths: int, s: int) -> dict[str, NDArray[np.float64]]:
    return {"shape_outlines_m": np.zeros((0, 4, 2)), "shape_yaws_deg": np.zeros(0),
            "shape_offsets_u": np.zeros(0), "shape_ratio_x": np.zeros((depths, 0, 0, 0, s)),
            "shape_ratio_y": np.zeros((depths, 0, 0, 0, s))}


def material_parameters(friction_angle_deg: float, dilation_angle_deg: float
                        ) -> tuple[float, float]:
    """Newton's ``(friction, dilatancy)`` for a sand of friction angle φ and dilation angle ψ.

    Newton's Drucker–Prager yield is ``|τ| <= μ p``: ``μ = tan φ``. Its plastic volumetric
    rate is ``dilatancy · μ`` times the shear rate, which the dilation angle makes
    ``tan ψ``: ``dilatancy = tan ψ / tan φ`` (0 for ψ = 0, 1 for associated flow).
    """
    friction = math.tan(math.radians(friction_angle_deg))
    return friction, math.tan(math.radians(dilation_angle_deg)) / friction


def fit_power_law(
    depths_m: NDArray[np.float64], drag_n: NDArray[np.float64]
) -> tuple[float, float]:
    """Least-squares fit of ``drag = c d**n`` in log space; returns ``(c, n)``.

    Needs at least two distinct positive depths and positive drags (else ValueError).
    """
    d = np.asarray(depths_m, dtype=np.float64)
    f = np.asarray(drag_n, dtype=np.float64)
    if d.shape != f.shape or d.size < 2 or np.unique(d).size < 2:
        raise ValueError("a power-law fit needs at least two distinct depths, one drag each")
    if not (np.all(np.isfinite(d)) and np.all(np.isfinite(f)) and np.all(d > 0) and np.all(f > 0)):
        raise ValueError("a power-law fit needs finite, positive depths and drags")
    n, log_c = np.polyfit(np.log(d), np.log(f), 1)
    return float(np.exp(log_c)), float(n)


def _axis_weights(grid: NDArray[np.float64], value: float) -> tuple[int, int, float]:
    """Indices ``i, j`` and weight ``w`` of ``value`` on ``grid`` (clamped at its ends):
    the value is ``(1 - w) g[i] + w g[j]``."""
    if grid.size == 1 or value <= grid[0]:
        return 0, 0, 0.0
    if value >= grid[-1]:
        return grid.size - 1, grid.size - 1, 0.0
    j = int(np.searchsorted(grid, value, side="right"))
    i = j - 1
    return i, j, float((value - grid[i]) / (grid[j] - grid[i]))


def _multilinear(tables: Sequence[NDArray[np.float64]],
                 axes: Sequence[tuple[int, int, float]]) -> tuple[float, ...]:
    """Each table's multilinear interpolation at the per-axis ``(i, j, w)`` of
    :func:`_axis_weights` (the tables' leading axes, in order)."""
    totals = [0.0] * len(tables)
    for corner in range(1 << len(axes)):
        index = []
        weight = 1.0
        for k, (i, j, w) in enumerate(axes):
            upper = (corner >> k) & 1
            index.append(j if upper else i)
            weight *= w if upper else 1 - w
        if weight == 0.0:
            continue
        at = tuple(index)
        for n, table in enumerate(tables):
            totals[n] += weight * float(table[at])
    return tuple(totals)


@dataclasses.dataclass(frozen=True)
class ResponseLibrary:
    """The arrays of a library (see the module docstring) and lookups into them."""

    depths_m: NDArray[np.float64]
    radii_m: NDArray[np.float64]
    offsets_u: NDArray[np.float64]
    s_m: NDArray[np.float64]
    travel_m: NDArray[np.float64]
    free_drag_n: NDArray[np.float64]
    ratio_x: NDArray[np.float64]
    ratio_y: NDArray[np.float64]
    #: voxel size (m), particles per cell, step (s), iterations, friction, dilatancy,
    #: density (kg/m³), speed (m/s), build CPU time (s): how it was made.
    settings: NDArray[np.float64]
    #: Shape tables (module docstring); empty in a library of cylinders only.
    shape_outlines_m: NDArray[np.float64] = dataclasses.field(
        default_factory=lambda: np.zeros((0, 4, 2)))
    shape_yaws_deg: NDArray[np.float64] = dataclasses.field(default_factory=lambda: np.zeros(0))
    shape_offsets_u: NDArray[np.float64] = dataclasses.field(
        default_factory=lambda: np.zeros(0))
    shape_ratio_x: NDArray[np.float64] | None = None
    shape_ratio_y: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        empty = _empty_shape_arrays(self.depths_m.size, self.s_m.size)
        for name in ("shape_ratio_x", "shape_ratio_y"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, empty[name])
        for name, dims in _ARRAYS.items():
            value = getattr(self, name)
            if value.ndim != len(dims):
                raise ValueError(f"library array {name!r} must have {len(dims)} dimension(s)")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"library array {name!r} holds a non-finite value")
        sizes: dict[str, int] = {}
        for name, dims in _ARRAYS.items():
            for axis, dim in enumerate(dims):
                n = getattr(self, name).shape[axis]
                if sizes.setdefault(dim, n) != n:
                    raise ValueError(f"library array {name!r}: axis {dim!r} has {n} entries, "
                                     f"others have {sizes[dim]}")
        for name in ("depths_m", "radii_m", "offsets_u", "s_m", "travel_m"):
            grid = getattr(self, name)
            if grid.size == 0 or np.any(np.diff(grid) <= 0):
                raise ValueError(f"library grid {name!r} must be non-empty and increasing")
        if self.shape_count:
            for name in ("shape_yaws_deg", "shape_offsets_u"):
                grid = getattr(self, name)
                if grid.size == 0 or np.any(np.diff(grid) <= 0):
                    raise ValueError(f"library grid {name!r} must be non-empty and increasing")
            yaws = self.shape_yaws_deg
            if yaws[0] < 0 or yaws[-1] > 90:
                raise ValueError("library grid 'shape_yaws_deg' must lie in 0 ... 90")
            if self.shape_outlines_m.shape[2] != 2 or self.shape_outlines_m.shape[1] < 3:
                raise ValueError("library array 'shape_outlines_m' must hold (x, y) outlines "
                                 "of at least 3 points")
        if np.any(self.free_drag_n <= 0):
            raise ValueError("library array 'free_drag_n' must be positive")

    @property
    def shape_count(self) -> int:
        """How many shapes have tables (0: every object is met as its equivalent cylinder)."""
        return int(self.shape_outlines_m.shape[0])

    def match_shape(self, outline_m: NDArray[np.float64]) -> tuple[int, float] | None:
        """The shape table that describes an object, and how it is turned.

        ``outline_m`` is the object's outline in its own frame (before its orientation).
        Returns ``(index, turn_deg)``: the object's outline is the table's outline turned
        by ``turn_deg`` (a multiple of 90°), so its yaw to a heading is its orientation plus
        ``turn_deg`` minus the heading. None when no table matches (within 3 mm or 5 % of
        its size on every direction of the support function).
        """
        target = support_function(outline_m)
        quarter = _SUPPORT_DIRECTIONS // 4
        for index in range(self.shape_count):
            entry = support_function(self.shape_outlines_m[index])
            tolerance = max(_MATCH_TOLERANCE_M, _MATCH_TOLERANCE_FRACTION * float(entry.max()))
            for turn in range(4):
                if np.max(np.abs(np.roll(entry, turn * quarter) - target)) <= tolerance:
                    return index, 90.0 * turn
        return None

    def shape_ratio(self, depth_m: float, shape: int, yaw_deg: float, offset_u: float,
                    s_m: float) -> tuple[float, float]:
        """Force / free drag along x and y towards shape ``shape`` at yaw ``yaw_deg`` (any
        angle) and signed offset ``offset_u`` (+: the object on the plate's left).

        The shapes are symmetric about both their axes: a yaw ψ is the yaw ψ + 180°, and
        mirrored across the heading it is -ψ with the offset and the y force reversed.
        """
        yaw = (yaw_deg + 90.0) % 180.0 - 90.0  # in [-90, 90)
        sign = 1.0
        if yaw < 0:
            yaw, offset_u, sign = -yaw, -offset_u, -1.0
        assert self.shape_ratio_x is not None and self.shape_ratio_y is not None
        axes = [
            _axis_weights(self.depths_m, depth_m),
            _axis_weights(self.shape_yaws_deg, yaw),
            _axis_weights(self.shape_offsets_u, offset_u),
            _axis_weights(self.s_m, s_m),
        ]
        # One shape's tables (a view): 16 corners a step, not 32.
        rx, ry = _multilinear((self.shape_ratio_x[:, shape], self.shape_ratio_y[:, shape]),
                              axes)
        return rx, sign * ry

    @property
    def drag_law(self) -> tuple[float, float]:
        """``(c, n)`` of ``drag = c d**n`` fitted to the steady free drag of each depth."""
        return fit_power_law(self.depths_m, self.steady_drag_n)

    @property
    def steady_drag_n(self) -> NDArray[np.float64]:
        """Mean free drag over the last half of the travel, per depth."""
        half = self.travel_m >= self.travel_m[-1] / 2
        return np.asarray(self.free_drag_n[:, half].mean(axis=1), dtype=np.float64)

    def free_drag(self, depth_m: float, travel_m: float) -> float:
        """Free drag (N) at ``depth_m`` after ``travel_m`` of a movement (start-up included)."""
        i, j, w = _axis_weights(self.travel_m, travel_m)
        row = (1 - w) * self.free_drag_n[:, i] + w * self.free_drag_n[:, j]
        if depth_m < self.depths_m[0]:
            # Shallower than the grid: scale the shallowest row by the fitted power law.
            _c, n = self.drag_law
            return float(row[0] * (depth_m / self.depths_m[0]) ** n)
        a, b, v = _axis_weights(self.depths_m, depth_m)
        return float((1 - v) * row[a] + v * row[b])

    def ratio(self, depth_m: float, radius_m: float, offset_u: float, s_m: float
              ) -> tuple[float, float]:
        """Force / free drag along x and y (object on the +y side) at one configuration."""
        axes = [
            _axis_weights(self.depths_m, depth_m),
            _axis_weights(self.radii_m, radius_m),
            _axis_weights(self.offsets_u, offset_u),
            _axis_weights(self.s_m, s_m),
        ]
        rx, ry = _multilinear((self.ratio_x, self.ratio_y), axes)
        return rx, ry


def save_library(path: Path, library: ResponseLibrary) -> None:
    """Write ``library`` as an uncompressed-free ``.npz`` of plain arrays."""
    arrays = {name: np.asarray(getattr(library, name)) for name in _ARRAYS}
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]


def load_library(path: Path) -> ResponseLibrary:
    """Read a library written by :func:`save_library` (no pickles); a located ValueError if bad.

    The file must be a regular file; each array's declared shape and dtype are read from its
    header before anything is decompressed (at most :data:`MAX_LIBRARY_BYTES` in all), and
    every array must hold real numbers.
    """
    try:
        with open_regular(path) as stream:
            data = read_npz(stream, keep=lambda name: name in _ARRAYS,
                            max_bytes=MAX_LIBRARY_BYTES)
    except FileNotFoundError:
        raise ValueError(f"{path}: no response library there (build one with "
                         "python -m hapticframe_mpm_sand.build_library)") from None
    except BoundedReadError as error:
        raise ValueError(f"{path}: cannot read the response library ({error})") from None
    missing = sorted(set(_ARRAYS) - set(data) - _OPTIONAL)
    if missing:
        raise ValueError(f"{path}: library lacks array(s) {', '.join(missing)}")
    if not _OPTIONAL <= set(data):  # an older library: cylinders only
        data = {**data, **_empty_shape_arrays(data["depths_m"].size, data["s_m"].size)}
    arrays = {}
    for name in _ARRAYS:
        if data[name].dtype.kind not in "iuf":
            raise ValueError(f"{path}: library array {name!r} holds {data[name].dtype} values, "
                             "not numbers")
        arrays[name] = np.asarray(data[name], dtype=np.float64)
    try:
        return ResponseLibrary(**arrays)
    except ValueError as error:
        raise ValueError(f"{path}: {error}") from error
