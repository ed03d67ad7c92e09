"""Empirical mode decomposition (EMD) in numpy/scipy, with the thesis's stopping rules.

The decomposition writes a signal as ``x = sum_j IMF_j + r`` (dissertation eq. 2.1). Each
intrinsic mode function (IMF) is sifted out of the current residue by repeatedly
subtracting the mean of two cubic-spline envelopes, one through the local maxima and one
through the local minima.

Choices, and why
----------------
- **Envelopes**: the cubic spline of :class:`scipy.interpolate.CubicSpline` with its default
  not-a-knot ends (the spline PyEMD's default ``"cubic"`` uses), evaluated on the sample
  grid. :func:`cubic_spline` solves the same banded system directly with LAPACK: EMD
  builds two splines per sifting iteration, and ``CubicSpline(t, v)(grid)`` took ~250 µs
  against ~50 µs here (12–40 knots), most of it input checking. The tests pin
  :func:`cubic_spline` to ``CubicSpline`` (1e-12 of the values' scale).
- **Ends**: two extrema are mirrored beyond each end (Rilling's rule: the mirror axis is the
  outermost extremum, or the end sample itself when the signal leaves the window beyond
  that extremum), so the envelopes are interpolated, not extrapolated, near the ends.
- **Sifting stop**: the Cauchy-type SD ratio ``sum(m**2) / sum(h**2)`` of the mean envelope
  ``m`` to the proto-IMF ``h`` falls below ``sd_threshold``, or ``max_sifts`` iterations
  have run (then the current proto-IMF is accepted; there is no exception, so a streaming
  loop never stalls).
- **Decomposition stop** (the thesis's rule, section 2.4.1.1): after extracting IMF_k, stop
  when ``||r_k|| < residue_ratio * ||IMF_k||``, or when the residue has fewer than three
  extrema (it is monotonic or a single hump and cannot be sifted), or when ``max_imfs`` IMFs
  have been extracted.
- **Scale invariance**: the signal is centred and divided by its standard deviation before
  sifting and the IMFs are scaled back, and every threshold is a ratio, so ``c * x`` gives
  ``c * IMFs`` for any ``c > 0`` (PyEMD's absolute ``range_thr`` / ``total_power_thr``
  change the IMF count with the signal's units).
- **Guards**: non-finite input raises :class:`ValueError`; a constant signal (spread within
  64 ulps of its magnitude) and a signal of fewer than 4 samples (too short for three
  extrema) give zero IMFs, ``n_found = 0`` and ``residue = x``.
- **Output**: always ``(max_imfs, n)``, zero rows after the ``n_found`` IMFs actually found;
  the residue is ``x - imfs.sum(axis=0)``, so IMFs plus residue rebuild ``x`` to rounding.
- **Speed**: the functions below make ~100 small numpy calls per sifting iteration. When
  numba is installed, :func:`emd` runs the same algorithm compiled
  (:mod:`._emd_kernel`, ``backend="auto"``), ≈ 15× faster on 512-sample pac windows; this
  module stays the readable reference the kernel is tested against.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg.lapack import dgbsv as _dgbsv

from ._validation import as_count, as_real

__all__ = [
    "MIN_SAMPLES",
    "EMDResult",
    "cubic_spline",
    "emd",
    "find_extrema",
    "mean_envelope",
    "numba_available",
    "sift",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]

#: Shortest signal that is decomposed; shorter ones cannot hold three interior extrema.
MIN_SAMPLES = 4

# A spread within this many ulps of the signal's magnitude is rounding noise: "constant".
_CONSTANT_ULPS = 64.0


@dataclass(frozen=True)
class EMDResult:
    """The decomposition of one signal.

    Attributes
    ----------
    imfs : (max_imfs, n) float64
        IMFs, highest frequency first; rows ``n_found`` onwards are zero.
    residue : (n,) float64
        ``x - imfs.sum(axis=0)``.
    n_found : int
        How many IMFs were extracted before a stopping rule fired.
    sift_counts : (max_imfs,) int
        Sifting iterations spent on each IMF (0 for the zero-padded rows).
    """

    imfs: FloatArray
    residue: FloatArray
    n_found: int
    sift_counts: NDArray[np.int64]


def cubic_spline(knots: FloatArray, values: FloatArray, grid: FloatArray) -> FloatArray:
    """The not-a-knot cubic spline through ``(knots, values)``, evaluated at ``grid``.

    Equal to ``scipy.interpolate.CubicSpline(knots, values)(grid)`` (its default
    ``bc_type="not-a-knot"``): two knots give the line, three the parabola through them.
    Solved for the second derivatives ``M`` with a (2, 2)-banded system (LAPACK ``dgbsv``,
    partial pivoting); the not-a-knot rows
    (continuous third derivative at the second and the second-to-last knot) are the only
    ones reaching two places off the diagonal. Points outside the knots are extrapolated
    with the end pieces.

    Parameters
    ----------
    knots : (n,) float64
        Strictly increasing, n ≥ 2.
    values : (n,) float64
    grid : (p,) float64
    """
    n = knots.size
    h = knots[1:] - knots[:-1]
    slope = (values[1:] - values[:-1]) / h
    if n == 2:
        return values[0] + slope[0] * (grid - knots[0])
    if n == 3:  # the parabola through three points, in Newton form
        curvature = (slope[1] - slope[0]) / (knots[2] - knots[0])
        return values[0] + (grid - knots[0]) * (slope[0] + curvature * (grid - knots[1]))
    # LAPACK band storage for dgbsv with 2 sub- and 2 super-diagonals (2 extra rows of
    # workspace on top): ab[4 + i - j, j] = A[i, j].
    ab = np.zeros((7, n))
    ab[5, : n - 2] = h[:-1]  # A[i, i-1], interior rows
    ab[4, 1 : n - 1] = 2.0 * (h[:-1] + h[1:])  # A[i, i]
    ab[3, 2:] = h[1:]  # A[i, i+1]
    # Not-a-knot: h1*M0 - (h0 + h1)*M1 + h0*M2 = 0, and its mirror image at the end.
    ab[4, 0], ab[3, 1], ab[2, 2] = h[1], -(h[0] + h[1]), h[0]
    ab[6, n - 3], ab[5, n - 2], ab[4, n - 1] = h[-1], -(h[-2] + h[-1]), h[-2]
    rhs = np.zeros(n)
    rhs[1:-1] = 6.0 * (slope[1:] - slope[:-1])
    # dgbsv directly: scipy.linalg.solve_banded's checks cost ~15x the solve at this size.
    _, _, m, info = _dgbsv(2, 2, ab, rhs, overwrite_ab=1, overwrite_b=1)
    if info != 0:
        raise ValueError(f"spline system is singular (LAPACK info {info}); knots must differ")
    # Power form per piece, gathered once per grid point and evaluated by Horner's rule.
    coefficients = np.empty((n - 1, 5))
    coefficients[:, 0] = (m[1:] - m[:-1]) / (6.0 * h)
    coefficients[:, 1] = 0.5 * m[:-1]
    coefficients[:, 2] = slope - h * (2.0 * m[:-1] + m[1:]) / 6.0
    coefficients[:, 3] = values[:-1]
    coefficients[:, 4] = knots[:-1]
    piece = np.searchsorted(knots, grid, side="right") - 1
    np.minimum(piece, n - 2, out=piece)
    np.maximum(piece, 0, out=piece)
    c = coefficients[piece]
    dx = grid - c[:, 4]
    return ((c[:, 0] * dx + c[:, 1]) * dx + c[:, 2]) * dx + c[:, 3]


def find_extrema(h: FloatArray) -> tuple[IntArray, IntArray]:
    """Indices of the interior local maxima and minima of ``h``.

    A flat run (equal neighbours) that rises before and falls after counts as one maximum at
    its middle sample, and vice versa for minima; runs touching either end are ignored.
    """
    d = h[1:] - h[:-1]
    # Drop zero steps so that a plateau is seen as one step between its neighbours.
    moving = (d != 0.0).nonzero()[0]
    if moving.size < 2:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    rising = d[moving] > 0.0
    turns = (rising[1:] != rising[:-1]).nonzero()[0]
    # The extremum lies between the end of step moving[i] and the start of step moving[i+1].
    first = moving[turns] + 1
    last = moving[turns + 1]
    position = (first + last) // 2
    rising_before = rising[turns]
    return position[rising_before], position[~rising_before]


def _mirror_start(
    h: FloatArray, imax: IntArray, imin: IntArray, n_mirror: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Mirrored (position, value) pairs before the start, for maxima then minima."""
    if imax[0] < imin[0]:  # the first extremum is a maximum
        if h[0] > h[imin[0]] and imax.size > 1:
            axis, mx, mn = imax[0], imax[1 : n_mirror + 1], imin[:n_mirror]
            mx_val, mn_val = h[mx], h[mn]
        else:  # the start sample acts as a minimum, mirrored about itself
            axis, mx = 0, imax[:n_mirror]
            mn = np.concatenate(([0], imin[: n_mirror - 1]))
            mx_val, mn_val = h[mx], h[mn]
    else:
        if h[0] < h[imax[0]] and imin.size > 1:
            axis, mx, mn = imin[0], imax[:n_mirror], imin[1 : n_mirror + 1]
            mx_val, mn_val = h[mx], h[mn]
        else:
            axis, mn = 0, imin[:n_mirror]
            mx = np.concatenate(([0], imax[: n_mirror - 1]))
            mx_val, mn_val = h[mx], h[mn]
    t_mx = 2.0 * axis - mx
    t_mn = 2.0 * axis - mn
    # Mirrored about an extremum, the outermost point of either set may still fall inside
    # the window; then the start sample is the axis instead (as Rilling's code does).
    if axis != 0 and (t_mx.min() > 0 or t_mn.min() > 0):
        mx, mn = imax[:n_mirror], imin[:n_mirror]
        t_mx, t_mn = -mx.astype(np.float64), -mn.astype(np.float64)
        mx_val, mn_val = h[mx], h[mn]
    return t_mx[::-1], mx_val[::-1], t_mn[::-1], mn_val[::-1]


def _mirror_end(
    h: FloatArray, imax: IntArray, imin: IntArray, n_mirror: int
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Mirrored (position, value) pairs after the end: reflect, mirror the start, reflect."""
    last = h.size - 1
    t_mx, v_mx, t_mn, v_mn = _mirror_start(h[::-1], last - imax[::-1], last - imin[::-1], n_mirror)
    return (last - t_mx)[::-1], v_mx[::-1], (last - t_mn)[::-1], v_mn[::-1]


def mean_envelope(h: FloatArray, imax: IntArray, imin: IntArray, n_mirror: int = 2) -> FloatArray:
    """Mean of the cubic-spline envelopes through the (mirrored) maxima and minima of ``h``.

    Needs at least one maximum and one minimum.
    """
    grid = np.arange(h.size, dtype=np.float64)
    lt_mx, lv_mx, lt_mn, lv_mn = _mirror_start(h, imax, imin, n_mirror)
    rt_mx, rv_mx, rt_mn, rv_mn = _mirror_end(h, imax, imin, n_mirror)
    t_max = np.concatenate((lt_mx, imax, rt_mx), dtype=np.float64)
    v_max = np.concatenate((lv_mx, h[imax], rv_mx))
    t_min = np.concatenate((lt_mn, imin, rt_mn), dtype=np.float64)
    v_min = np.concatenate((lv_mn, h[imin], rv_mn))
    upper = cubic_spline(t_max, v_max, grid)
    lower = cubic_spline(t_min, v_min, grid)
    return 0.5 * (upper + lower)


def sift(
    residue: FloatArray,
    *,
    sd_threshold: float = 0.01,
    max_sifts: int = 50,
    n_mirror: int = 2,
) -> tuple[FloatArray, int]:
    """Sift one IMF out of ``residue``; return it and the number of iterations used.

    Iteration stops when ``sum(m**2) / sum(h**2) < sd_threshold`` (``m`` the mean envelope,
    ``h`` the proto-IMF before subtracting it), when ``max_sifts`` iterations have run, or
    when the proto-IMF has too few extrema for two envelopes. ``sd_threshold = 0`` sifts
    exactly ``max_sifts`` times (PyEMD's ``FIXE`` mode).
    """
    h = residue.copy()
    count = 0
    while count < max_sifts:
        imax, imin = find_extrema(h)
        if imax.size + imin.size < 3 or imax.size == 0 or imin.size == 0:
            break
        m = mean_envelope(h, imax, imin, n_mirror)
        energy = float(h @ h)
        h = h - m
        count += 1
        if energy == 0.0 or float(m @ m) < sd_threshold * energy:
            break
    return h, count


def numba_available() -> bool:
    """Whether the compiled kernel can run (numba is installed; checked without importing)."""
    return importlib.util.find_spec("numba") is not None


def _use_kernel(backend: str) -> bool:
    if backend == "numpy":
        return False
    if backend == "numba":
        if not numba_available():
            raise ImportError("backend='numba' needs numba: pip install 'numba>=0.60'")
        return True
    if backend == "auto":
        return numba_available()
    raise ValueError(f"backend must be 'auto', 'numba' or 'numpy', got {backend!r}")


def emd(
    signal: ArrayLike,
    max_imfs: int = 8,
    *,
    sd_threshold: float = 0.01,
    max_sifts: int = 50,
    residue_ratio: float = 0.1,
    n_mirror: int = 2,
    backend: str = "auto",
) -> EMDResult:
    """Decompose ``signal`` into at most ``max_imfs`` IMFs and a residue.

    Parameters
    ----------
    signal : (n,) array_like
        The samples (converted to float64).
    max_imfs : int
        Rows of the output; the decomposition stops here at the latest.
    sd_threshold : float
        Sifting stops when the mean envelope's energy is below this fraction of the
        proto-IMF's energy (Huang's SD, Cauchy type). 0 disables it (fixed sifting).
        The default 0.01 (about 4 sifts per IMF) was chosen with ``hapticframe bench
        emd-fidelity`` (``docs/benchmarks.md``, "EMD: sifting against fidelity").
    max_sifts : int
        Cap on sifting iterations per IMF.
    residue_ratio : float
        Stop once ``||residue|| < residue_ratio * ||last IMF||`` (the thesis's 10 %).
        0 disables the rule.
    n_mirror : int
        Extrema mirrored beyond each end.
    backend : {"auto", "numba", "numpy"}
        ``"numba"`` runs the compiled kernel of :mod:`._emd_kernel` (≈ 20× faster on
        pac windows; needs numba), ``"numpy"`` the functions of this module; ``"auto"``
        takes numba when it is installed. Both compute the same decomposition to rounding.

    Returns
    -------
    EMDResult

    Raises
    ------
    ValueError
        If the signal is not one-dimensional, holds NaN or infinity, or a setting is out of
        range.
    ImportError
        If ``backend="numba"`` and numba is not installed.
    """
    use_kernel = _use_kernel(backend)
    x = np.ascontiguousarray(signal, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"emd expects a one-dimensional signal, got shape {x.shape}")
    # One type per argument before the compiled kernel sees them: numba compiles a fresh
    # specialisation (11-70 s) for every new combination of argument types, so an int
    # sd_threshold or a numpy int32 max_sifts would otherwise cost a compile.
    max_imfs = as_count("max_imfs", max_imfs)
    max_sifts = as_count("max_sifts", max_sifts)
    n_mirror = as_count("n_mirror", n_mirror)
    sd_threshold = as_real("sd_threshold", sd_threshold)
    residue_ratio = as_real("residue_ratio", residue_ratio)
    if max_imfs < 1 or max_sifts < 1 or n_mirror < 1:
        raise ValueError("max_imfs, max_sifts and n_mirror must be at least 1")
    if not (sd_threshold >= 0.0 and residue_ratio >= 0.0):
        raise ValueError("sd_threshold and residue_ratio must be non-negative")
    if not np.isfinite(x).all():
        bad = int(np.flatnonzero(~np.isfinite(x))[0])
        raise ValueError(
            f"emd input holds NaN or infinity (first at sample {bad}); fill or drop invalid "
            "samples before decomposing"
        )
    n = x.size
    imfs = np.zeros((max_imfs, n))
    counts = np.zeros(max_imfs, dtype=np.int64)
    if n < MIN_SAMPLES:
        return EMDResult(imfs, x.copy(), 0, counts)
    if use_kernel:
        from ._emd_kernel import STATUS_CONSTANT, STATUS_OK, emd_kernel

        found, status = emd_kernel(
            x, imfs, counts, sd_threshold, max_sifts, residue_ratio, n_mirror
        )
        if status == STATUS_CONSTANT:
            return EMDResult(imfs, x.copy(), 0, counts)
        if status != STATUS_OK:
            raise ValueError("spline system is singular; knots must differ")
        return EMDResult(imfs, x - imfs.sum(axis=0), int(found), counts)
    offset = float(np.mean(x))
    spread = float(np.ptp(x))
    if spread <= _CONSTANT_ULPS * np.finfo(np.float64).eps * float(np.max(np.abs(x))):
        return EMDResult(imfs, x.copy(), 0, counts)
    scale = float(np.std(x - offset))
    r = (x - offset) / scale
    found = 0
    for k in range(max_imfs):
        imax, imin = find_extrema(r)
        if imax.size + imin.size < 3 or imax.size == 0 or imin.size == 0:
            break  # monotonic or a single turning point: r is the final residue
        h, counts[k] = sift(r, sd_threshold=sd_threshold, max_sifts=max_sifts, n_mirror=n_mirror)
        imfs[k] = h
        r = r - h
        found = k + 1
        if residue_ratio > 0.0 and np.linalg.norm(r) < residue_ratio * np.linalg.norm(h):
            break
    imfs *= scale
    return EMDResult(imfs, x - imfs.sum(axis=0), found, counts)
