"""Pure array functions: judging occupancy maps, and rotations.

Rotations (REP 103 frames; quaternions scalar first, ``(w, x, y, z)``): the matrix of a
quaternion or of fixed-axis roll, pitch and yaw, and back. Device emulators, drivers and
the force observer share them; ``scipy.spatial.transform.Rotation`` is the tests'
reference, and these closed forms cost a few microseconds per call where it costs tens.

Maps:

Any map can be sampled on a grid with :meth:`~hapticframe.kinds.Map.query`; these functions
turn such a grid into the object estimates of the dissertation (section 3.4.3.2): the
outline as a level curve and the centroid, and compare them with a true outline by the
directed Hausdorff distance in both directions.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "blob_centroid",
    "directed_hausdorff_both",
    "level_outlines",
    "main_outline",
    "rotation_matrix_from_rpy_deg",
    "rotation_matrix_from_wxyz",
    "sample_grid",
    "wxyz_from_rotation_matrix",
]

FloatArray = NDArray[np.float64]


def sample_grid(bounds_m: tuple[float, float, float, float], spacing_m: float) -> tuple[
    FloatArray, FloatArray, FloatArray
]:
    """Cell-centre coordinates of a grid over ``(x_min, x_max, y_min, y_max)``.

    Returns
    -------
    xs : (nx,) float64
    ys : (ny,) float64
    points : (ny * nx, 2) float64
        Row-major points, so ``values.reshape(ny, nx)`` matches ``(ys, xs)``.
    """
    x_min, x_max, y_min, y_max = (float(b) for b in bounds_m)
    if not spacing_m > 0:
        raise ValueError("spacing_m must be positive")
    if not (x_max > x_min and y_max > y_min):
        raise ValueError("bounds must have positive width and height")
    nx = max(1, int(np.ceil((x_max - x_min) / spacing_m)))
    ny = max(1, int(np.ceil((y_max - y_min) / spacing_m)))
    xs = x_min + (np.arange(nx) + 0.5) * (x_max - x_min) / nx
    ys = y_min + (np.arange(ny) + 0.5) * (y_max - y_min) / ny
    gx, gy = np.meshgrid(xs, ys)
    return xs, ys, np.column_stack([gx.ravel(), gy.ravel()])


def _check_grid(xs: ArrayLike, ys: ArrayLike, values: ArrayLike) -> tuple[FloatArray, ...]:
    x = np.asarray(xs, dtype=np.float64)
    y = np.asarray(ys, dtype=np.float64)
    v = np.asarray(values, dtype=np.float64)
    if v.shape != (y.size, x.size):
        raise ValueError(
            f"values must have shape (len(ys), len(xs)) = {(y.size, x.size)}, got {v.shape}"
        )
    if not np.all(np.isfinite(v)):
        raise ValueError("values contain NaN or infinity")
    return x, y, v


def level_outlines(
    xs: ArrayLike, ys: ArrayLike, values: ArrayLike, level: float
) -> list[FloatArray]:
    """Closed curves where ``values`` crosses ``level`` (marching squares).

    Curves touching the grid's edge are closed along the edge, so an object at the border
    of the region still gets a closed outline.

    Returns
    -------
    list of (k, 2) float64
        One array of points per curve, longest first; empty when nothing reaches ``level``.
    """
    import contourpy  # light (numpy only), imported on use

    x, y, v = _check_grid(xs, ys, values)
    if v.size == 0 or v.max() < level or x.size < 2 or y.size < 2:
        return []
    # Pad with a value below the level so curves at the border close along it.
    low = min(float(v.min()), level) - 1.0
    padded = np.pad(v, 1, constant_values=low)
    dx = x[1] - x[0]
    dy = y[1] - y[0]
    px = np.concatenate([[x[0] - dx / 2], x, [x[-1] + dx / 2]])
    py = np.concatenate([[y[0] - dy / 2], y, [y[-1] + dy / 2]])
    generator = contourpy.contour_generator(px, py, padded, line_type="Separate")
    lines = [np.asarray(line, dtype=np.float64) for line in generator.lines(level)]
    lines = [line for line in lines if len(line) >= 3]
    x_lo, x_hi, y_lo, y_hi = x[0] - dx / 2, x[-1] + dx / 2, y[0] - dy / 2, y[-1] + dy / 2
    for line in lines:  # keep padded-edge vertices on the region's edge
        np.clip(line[:, 0], x_lo, x_hi, out=line[:, 0])
        np.clip(line[:, 1], y_lo, y_hi, out=line[:, 1])
    return sorted(lines, key=len, reverse=True)


def main_outline(
    xs: ArrayLike, ys: ArrayLike, values: ArrayLike, level: float,
    near_m: ArrayLike | None = None,
) -> FloatArray | None:
    """The outline of the estimated object: the level curve around the chosen blob.

    The blob is the connected region above ``level`` that holds the most occupancy mass,
    or, when ``near_m`` is given, the one closest to that point.
    """
    x, y, v = _check_grid(xs, ys, values)
    lines = level_outlines(x, y, v, level)
    if not lines:
        return None
    target = blob_centroid(x, y, v, level, near_m=near_m)
    if target is None:
        return lines[0]
    # The curve whose own centroid is closest to the blob's centroid.
    return min(lines, key=lambda line: float(np.linalg.norm(line.mean(axis=0) - target)))


def blob_centroid(
    xs: ArrayLike, ys: ArrayLike, values: ArrayLike, level: float,
    near_m: ArrayLike | None = None,
) -> FloatArray | None:
    """Occupancy-weighted centroid of one connected region where ``values >= level``.

    Parameters
    ----------
    xs, ys : 1-D arrays
        Grid coordinates; ``values`` has shape ``(len(ys), len(xs))``.
    level : float
        Threshold (0.6 in the dissertation).
    near_m : (2,) array, optional
        Pick the region closest to this point instead of the heaviest one.

    Returns
    -------
    (2,) float64 or None
        None when no cell reaches ``level``.
    """
    from scipy import ndimage  # imported on use: keeps `import hapticframe` fast

    x, y, v = _check_grid(xs, ys, values)
    mask = v >= level
    if not mask.any():
        return None
    labels, count = ndimage.label(mask)
    index = np.arange(1, count + 1)
    weights = np.where(mask, v, 0.0)
    gx, gy = np.meshgrid(x, y)
    mass = ndimage.sum(weights, labels, index)
    cx = ndimage.sum(weights * gx, labels, index) / mass
    cy = ndimage.sum(weights * gy, labels, index) / mass
    centres: NDArray[np.float64] = np.column_stack([cx, cy])
    if near_m is not None:
        chosen = int(np.argmin(np.linalg.norm(centres - np.asarray(near_m, dtype=float), axis=1)))
    else:
        chosen = int(np.argmax(mass))
    centre: NDArray[np.float64] = centres[chosen]
    return centre


def directed_hausdorff_both(estimate: ArrayLike, truth: ArrayLike) -> tuple[float, float]:
    """Directed Hausdorff distances (Taha & Hanbury, via scipy) in both directions.

    Returns
    -------
    (estimate_to_truth, truth_to_estimate) : tuple of float
        The first measures false structure, the second missed structure.
    """
    from scipy.spatial.distance import directed_hausdorff

    a = np.asarray(estimate, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(truth, dtype=np.float64).reshape(-1, 2)
    if len(a) == 0 or len(b) == 0:
        raise ValueError("both outlines need at least one point")
    # rng left at its default: reproducible on scipy before and after 1.15.
    return float(directed_hausdorff(a, b)[0]), float(directed_hausdorff(b, a)[0])


def rotation_matrix_from_wxyz(quaternion: ArrayLike) -> FloatArray:
    """The (3, 3) rotation matrix of a quaternion ``(w, x, y, z)``, normalised first.

    Raises
    ------
    ValueError
        When the quaternion is not 4 finite numbers or has (nearly) zero norm.
    """
    q = np.asarray(quaternion, dtype=np.float64).reshape(-1)
    if q.shape != (4,) or not np.all(np.isfinite(q)):
        raise ValueError(f"a quaternion is 4 finite numbers (w, x, y, z), got {q.tolist()}")
    norm = math.sqrt(float(q @ q))
    if norm < 1e-9:
        raise ValueError("a rotation quaternion cannot be zero")
    w, x, y, z = (q / norm).tolist()
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def wxyz_from_rotation_matrix(rotation: ArrayLike) -> FloatArray:
    """The unit quaternion ``(w, x, y, z)`` with ``w >= 0`` of a rotation matrix.

    Shepperd's method: it divides by the largest of the four diagonal combinations, so it is
    accurate for every rotation, half turns included.
    """
    m = np.asarray(rotation, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"a rotation matrix is 3 x 3 and finite, got shape {m.shape}")
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    k = int(np.argmax([trace, m[0, 0], m[1, 1], m[2, 2]]))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        q = [0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s]
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [(m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s]
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s]
    out = np.asarray(q, dtype=np.float64)
    out /= np.linalg.norm(out)
    return -out if out[0] < 0 else out


def rotation_matrix_from_rpy_deg(rpy_deg: ArrayLike) -> FloatArray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``: fixed-axis roll, pitch and yaw in degrees (REP 103)."""
    roll, pitch, yaw = np.radians(np.asarray(rpy_deg, dtype=np.float64).reshape(3)).tolist()
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])
