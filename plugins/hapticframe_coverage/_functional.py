"""Pure functions of coverage path planning and next-best-path selection (section 3.4.4).

Rectangles are ``bounds = (x_min, x_max, y_min, y_max)`` in metres; sweep angles are measured
counter-clockwise from +x and matter modulo 180° (a line and its reverse share an angle).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "Bounds",
    "allowed_sweep_mask",
    "angle_gap_deg",
    "bearing_gap_scores_deg",
    "binary_search_order",
    "free_runs",
    "inside_or_near",
    "largest_angular_gap_deg",
    "line_scores",
    "longer_side_angle_deg",
    "outer_last_order",
    "parallel_lines",
    "points_along",
    "ray_exit_distance",
    "sample_sweep_angle_deg",
    "shrink_bounds",
    "uncertainty_fraction",
]

FloatArray = NDArray[np.float64]
Bounds = tuple[float, float, float, float]

_AXIS_EPS = 1e-12


def _check_bounds(bounds: Sequence[float]) -> Bounds:
    x_min, x_max, y_min, y_max = (float(b) for b in bounds)
    if not all(math.isfinite(v) for v in (x_min, x_max, y_min, y_max)):
        raise ValueError("bounds must be finite")
    if not (x_max > x_min and y_max > y_min):
        raise ValueError("bounds must have positive width and height")
    return x_min, x_max, y_min, y_max


def longer_side_angle_deg(bounds: Sequence[float]) -> float:
    """Sweep angle parallel to the rectangle's longer side: the fewest parallel lines."""
    x_min, x_max, y_min, y_max = _check_bounds(bounds)
    return 0.0 if x_max - x_min >= y_max - y_min else 90.0


def parallel_lines(
    bounds: Sequence[float], angle_deg: float, spacing_m: float, min_length_m: float = 1e-3,
    *, between: bool = False,
) -> tuple[FloatArray, FloatArray]:
    """Parallel straight lines at ``angle_deg`` covering a rectangle, clipped to it.

    The rectangle's extent across the lines is split into ``ceil(width / spacing)`` equal
    strips and one line runs along the middle of each, so neighbouring lines are at most
    ``spacing_m`` apart and the outermost ones half a strip from the boundary. With
    ``between`` the lines run along the borders between neighbouring strips instead (midway
    between the lines without it; one fewer, none for a single strip). Every line
    runs in the direction ``(cos θ, sin θ)``; lines are ordered by their offset along the
    normal ``(−sin θ, cos θ)``. Corner slivers shorter than ``min_length_m`` are dropped.

    Returns
    -------
    starts, ends : (L, 2) float64
        End points on the rectangle's boundary.
    """
    x_min, x_max, y_min, y_max = _check_bounds(bounds)
    if not (math.isfinite(spacing_m) and spacing_m > 0):
        raise ValueError("spacing_m must be finite and positive")
    if not math.isfinite(angle_deg):
        raise ValueError("angle_deg must be finite")
    theta = math.radians(angle_deg)
    u = np.array([math.cos(theta), math.sin(theta)])
    v = np.array([-u[1], u[0]])
    u[np.abs(u) < _AXIS_EPS] = 0.0
    v[np.abs(v) < _AXIS_EPS] = 0.0
    corners = np.array([[x_min, y_min], [x_max, y_min], [x_max, y_max], [x_min, y_max]])
    across = corners @ v
    lo, hi = float(across.min()), float(across.max())
    strips = max(1, math.ceil((hi - lo) / spacing_m - 1e-9))
    if between:
        offsets = lo + np.arange(1, strips) * (hi - lo) / strips
    else:
        offsets = lo + (np.arange(strips) + 0.5) * (hi - lo) / strips
    count = offsets.size
    origins = offsets[:, None] * v[None, :]
    t_lo = np.full(count, -np.inf)
    t_hi = np.full(count, np.inf)
    inside = np.ones(count, dtype=bool)
    for axis, (a, b) in enumerate(((x_min, x_max), (y_min, y_max))):
        if u[axis] == 0.0:  # parallel to this slab: inside it or not at all
            inside &= (origins[:, axis] >= a) & (origins[:, axis] <= b)
            continue
        t_a = (a - origins[:, axis]) / u[axis]
        t_b = (b - origins[:, axis]) / u[axis]
        t_lo = np.maximum(t_lo, np.minimum(t_a, t_b))
        t_hi = np.minimum(t_hi, np.maximum(t_a, t_b))
    keep = inside & (t_hi - t_lo > min_length_m)
    starts = origins[keep] + t_lo[keep, None] * u
    ends = origins[keep] + t_hi[keep, None] * u
    for points in (starts, ends):  # rounding must not put an end point outside
        np.clip(points[:, 0], x_min, x_max, out=points[:, 0])
        np.clip(points[:, 1], y_min, y_max, out=points[:, 1])
    return starts, ends


def binary_search_order(count: int) -> list[int]:
    """Line indices in binary-search order: the middle, then the quarters, the eighths...

    Breadth-first over halving intervals, so each pass halves the largest unexplored gap.

    >>> binary_search_order(7)
    [3, 1, 5, 0, 2, 4, 6]
    """
    if count < 0:
        raise ValueError("count must be non-negative")
    order: list[int] = []
    pending = deque([(0, count - 1)])
    while pending:
        lo, hi = pending.popleft()
        if lo > hi:
            continue
        mid = (lo + hi) // 2
        order.append(mid)
        pending.append((lo, mid - 1))
        pending.append((mid + 1, hi))
    return order


def outer_last_order(count: int) -> list[int]:
    """Binary-search order with the two outermost lines moved to the end.

    The outermost lines lie half a spacing from the region's edge, so an object (fully
    inside the region) is less often centred near them: they are raked last.

    >>> outer_last_order(5)
    [2, 3, 1, 0, 4]
    """
    order = binary_search_order(count)
    if count <= 2:
        return order
    edges = [0, count - 1]
    return [i for i in order if i not in edges] + edges


def angle_gap_deg(a_deg: float, b_deg: float) -> float:
    """Smallest difference between two line directions, modulo 180°, in [0, 90]."""
    d = (a_deg - b_deg) % 180.0
    return min(d, 180.0 - d)


def sample_sweep_angle_deg(
    rng: np.random.Generator, used_deg: Sequence[float], min_separation_deg: float = 30.0
) -> float:
    """A uniformly random sweep angle in [0, 180) at least ``min_separation_deg`` from others.

    Only 180/separation directions fit pairwise apart, so when no angle is far enough from
    all of ``used_deg`` the oldest ones are forgotten until one is (the most recent angle is
    never forgotten, and a separation up to 90° always leaves room next to one angle).

    Parameters
    ----------
    rng : numpy.random.Generator
    used_deg : sequence of float
        Angles used before, oldest first.
    min_separation_deg : float
        In [0, 90).
    """
    if not 0.0 <= min_separation_deg < 90.0:
        raise ValueError("min_separation_deg must lie in [0, 90)")
    recent = [float(a) % 180.0 for a in used_deg]
    while True:
        intervals = _free_intervals(recent, min_separation_deg)
        total = sum(b - a for a, b in intervals)
        if total > 1e-9:
            break
        recent = recent[1:]
    draw = float(rng.uniform(0.0, total))
    for a, b in intervals:
        if draw <= b - a:
            return (a + draw) % 180.0
        draw -= b - a
    a, b = intervals[-1]  # rounding at the very end of the last interval
    return b % 180.0


def _free_intervals(used: Sequence[float], separation: float) -> list[tuple[float, float]]:
    """Intervals of [0, 180) (unwrapped, may exceed 180) at least ``separation`` from ``used``."""
    if not used:
        return [(0.0, 180.0)]
    angles = sorted(set(used))
    out = []
    for i, a in enumerate(angles):
        b = angles[i + 1] if i + 1 < len(angles) else angles[0] + 180.0
        if b - a > 2 * separation:
            out.append((a + separation, b - separation))
    return out


def shrink_bounds(
    bounds: Sequence[float],
    centre_m: ArrayLike,
    keep_fraction: float,
    outer_bounds: Sequence[float],
    min_size_m: float,
) -> Bounds:
    """The region shrunk to ``keep_fraction`` of each side, re-centred and kept inside.

    Each side becomes ``max(keep_fraction · side, min_size_m)`` (never larger than it was or
    than the outer region), centred on ``centre_m`` and shifted to lie inside
    ``outer_bounds``.
    """
    x_min, x_max, y_min, y_max = _check_bounds(bounds)
    ox_min, ox_max, oy_min, oy_max = _check_bounds(outer_bounds)
    c = np.asarray(centre_m, dtype=np.float64).reshape(-1)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise ValueError("centre_m must be two finite numbers")
    if not 0.0 < keep_fraction <= 1.0:
        raise ValueError("keep_fraction must lie in (0, 1]")
    result = []
    for centre, (lo, hi), (olo, ohi) in zip(
        c, ((x_min, x_max), (y_min, y_max)), ((ox_min, ox_max), (oy_min, oy_max)), strict=True
    ):
        side = min(hi - lo, ohi - olo)
        side = min(side, max(keep_fraction * side, min_size_m))
        start = min(max(centre - side / 2, olo), ohi - side)
        result.extend([start, start + side])
    return result[0], result[1], result[2], result[3]


def points_along(
    starts: ArrayLike, ends: ArrayLike, step_m: float
) -> tuple[FloatArray, NDArray[np.intp]]:
    """Points every ≤ ``step_m`` along each segment, both ends included.

    Returns
    -------
    points : (p, 2) float64
    line_index : (p,) int
        The segment each point belongs to.
    """
    s = np.asarray(starts, dtype=np.float64).reshape(-1, 2)
    e = np.asarray(ends, dtype=np.float64).reshape(-1, 2)
    if s.shape != e.shape:
        raise ValueError("starts and ends must have the same shape")
    if not step_m > 0:
        raise ValueError("step_m must be positive")
    points, index = [], []
    for i, (a, b) in enumerate(zip(s, e, strict=True)):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / step_m))
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        points.append(a + t * (b - a))
        index.append(np.full(n + 1, i, dtype=np.intp))
    if not points:
        return np.empty((0, 2)), np.empty(0, dtype=np.intp)
    return np.concatenate(points), np.concatenate(index)


def line_scores(
    mean: ArrayLike,
    std: ArrayLike,
    points_m: ArrayLike,
    line_index: ArrayLike,
    centroid_m: ArrayLike,
    weights: Sequence[float],
    distance_scale_m: float,
    line_count: int,
) -> FloatArray:
    """Eq. 3.9 per candidate: Σ over its points of w1 m̂ + w2 std + w3 (‖x − x̂‖ / L)².

    Distances are divided by ``distance_scale_m`` (the planner passes the diagonal of the
    current region) so the three terms are all of order one.
    """
    m = np.asarray(mean, dtype=np.float64).reshape(-1)
    sd = np.asarray(std, dtype=np.float64).reshape(-1)
    p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    idx = np.asarray(line_index, dtype=np.intp).reshape(-1)
    if not (m.shape == sd.shape == idx.shape == (p.shape[0],)):
        raise ValueError("mean, std, line_index and points must have one entry per point")
    if not distance_scale_m > 0:
        raise ValueError("distance_scale_m must be positive")
    w1, w2, w3 = (float(w) for w in weights)
    d2 = np.sum((p - np.asarray(centroid_m, dtype=np.float64)) ** 2, axis=1) / distance_scale_m**2
    per_point = w1 * m + w2 * sd + w3 * d2
    # A weighted bincount is float64 already (numpy's stub says intp): astype copies nothing.
    totals = np.bincount(idx, weights=per_point, minlength=line_count)
    return totals.astype(np.float64, copy=False)


def uncertainty_fraction(std: ArrayLike, rule: str, uncertain_std: float) -> float:
    """How uncertain a region still is, as a fraction compared with λ to stop.

    ``"uncertain-area"``: the share of the region's area (cells of a uniform grid) whose std
    exceeds ``uncertain_std``; ``"mean-std"``: the mean std relative to 0.5, the largest std
    a probability in [0, 1] can have. An empty grid counts as fully uncertain.
    """
    sd = np.asarray(std, dtype=np.float64).reshape(-1)
    if sd.size == 0:
        return 1.0
    if not np.all(np.isfinite(sd)):
        raise ValueError("std contains NaN or infinity")
    if rule == "uncertain-area":
        return float(np.mean(sd > uncertain_std))
    if rule == "mean-std":
        return float(np.mean(sd) / 0.5)
    raise ValueError(f"unknown stop rule {rule!r}")


def largest_angular_gap_deg(bearings_deg: ArrayLike) -> float:
    """Widest gap (degrees) between directions on the full circle; 360 with none, and the
    complement of nothing (360) with one."""
    b = np.sort(np.mod(np.asarray(bearings_deg, dtype=np.float64).reshape(-1), 360.0))
    if b.size == 0:
        return 360.0
    if not np.all(np.isfinite(b)):
        raise ValueError("bearings must be finite")
    return float(np.max(np.diff(np.append(b, b[0] + 360.0))))


def bearing_gap_scores_deg(candidates_deg: ArrayLike, bearings_deg: ArrayLike) -> FloatArray:
    """For each candidate direction, the angular distance (0-180°) to the nearest bearing.

    With no bearings every candidate scores 180.
    """
    c = np.asarray(candidates_deg, dtype=np.float64).reshape(-1, 1)
    b = np.asarray(bearings_deg, dtype=np.float64).reshape(1, -1)
    if b.size == 0:
        return np.full(c.shape[0], 180.0)
    d = np.mod(c - b, 360.0)
    return np.min(np.minimum(d, 360.0 - d), axis=1)


def allowed_sweep_mask(
    candidates_deg: ArrayLike, used_deg: Sequence[float], min_separation_deg: float
) -> NDArray[np.bool_]:
    """Candidates whose line direction (modulo 180°) keeps ``min_separation_deg`` from the
    used ones; when none does, the oldest used angles are forgotten until some do (the most
    recent one never is), as in :func:`sample_sweep_angle_deg`."""
    if not 0.0 <= min_separation_deg < 90.0:
        raise ValueError("min_separation_deg must lie in [0, 90)")
    c = np.mod(np.asarray(candidates_deg, dtype=np.float64).reshape(-1), 180.0)
    recent = [float(a) % 180.0 for a in used_deg]
    while True:
        ok = np.ones(c.size, dtype=bool)
        for a in recent:
            d = np.mod(c - a, 180.0)
            ok &= np.minimum(d, 180.0 - d) >= min_separation_deg - 1e-9
        if ok.any() or len(recent) <= 1:
            return ok
        recent = recent[1:]


def ray_exit_distance(
    origin_m: ArrayLike, bearings_deg: ArrayLike, bounds: Sequence[float]
) -> FloatArray:
    """Distance from ``origin_m`` along each bearing to the boundary of the rectangle
    (0 when the origin lies outside it)."""
    x_min, x_max, y_min, y_max = _check_bounds(bounds)
    o = np.asarray(origin_m, dtype=np.float64).reshape(2)
    theta = np.radians(np.asarray(bearings_deg, dtype=np.float64).reshape(-1))
    u = np.column_stack([np.cos(theta), np.sin(theta)])
    out = np.full(theta.size, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, (lo, hi) in enumerate(((x_min, x_max), (y_min, y_max))):
            step = u[:, axis]
            exit_at = np.where(step > 0, (hi - o[axis]) / step,
                               np.where(step < 0, (lo - o[axis]) / step, np.inf))
            out = np.minimum(out, exit_at)
    inside = x_min <= o[0] <= x_max and y_min <= o[1] <= y_max
    return np.maximum(out, 0.0) if inside else np.zeros(theta.size)


def inside_or_near(points_m: ArrayLike, outlines: Sequence[ArrayLike], margin_m: float
                   ) -> NDArray[np.bool_]:
    """Which points lie inside any closed outline or within ``margin_m`` of it.

    Outlines are ``(k, 2)`` vertex arrays, closed implicitly (last vertex to first): the
    found objects, dilated by ``margin_m``.
    """
    p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    hit = np.zeros(len(p), dtype=bool)
    x, y = p[:, 0:1], p[:, 1:2]
    for outline in outlines:
        v = np.asarray(outline, dtype=np.float64).reshape(-1, 2)
        if len(v) == 0:
            continue
        a, b = v, np.roll(v, -1, axis=0)
        # Even-odd rule: a ray towards +x crosses the outline an odd number of times.
        crosses = (a[:, 1] > y) != (b[:, 1] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            x_at = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
        inside = np.count_nonzero(crosses & (x < x_at), axis=1) % 2 == 1
        d = b - a
        length2 = np.maximum(np.sum(d * d, axis=1), 1e-300)
        t = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / length2, 0.0, 1.0)
        gap = np.hypot(a[:, 0] + t * d[:, 0] - x, a[:, 1] + t * d[:, 1] - y).min(axis=1)
        hit |= inside | (gap <= margin_m)
    return hit


def free_runs(start_m: ArrayLike, end_m: ArrayLike, blocked: ArrayLike, min_length_m: float
              ) -> list[tuple[FloatArray, FloatArray]]:
    """The parts of the segment from ``start_m`` to ``end_m`` that are free.

    ``blocked`` flags equally spaced points from start to end (both included); each run of
    free points becomes a sub-segment (in the segment's direction) when at least
    ``min_length_m`` long.
    """
    a = np.asarray(start_m, dtype=np.float64)
    b = np.asarray(end_m, dtype=np.float64)
    flags = np.asarray(blocked, dtype=bool).reshape(-1)
    if flags.size < 2:
        return [] if flags.any() else [(a, b)]
    t = np.linspace(0.0, 1.0, flags.size)
    length = float(np.linalg.norm(b - a))
    out: list[tuple[FloatArray, FloatArray]] = []
    # Free runs start where blocked (or the virtual point before the start) turns free.
    padded = np.concatenate([[True], flags, [True]])
    starts = np.flatnonzero(padded[:-1] & ~padded[1:])
    stops = np.flatnonzero(~padded[:-1] & padded[1:])
    for i, j in zip(starts, stops, strict=True):
        t0, t1 = t[i], t[j - 1]
        if (t1 - t0) * length >= min_length_m:
            out.append((a + t0 * (b - a), a + t1 * (b - a)))
    return out
