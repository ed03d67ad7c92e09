"""Digital low-pass filtering shared by plugins: one home for the Butterworth design.

:func:`butterworth_sos` designs the filter (scipy's ``signal.butter(..., output="sos")`` is
its reference), :func:`sos_step_state` gives the state at rest on a constant input
(``signal.sosfilt_zi``), and :func:`sos_filter` runs it with the state carried across calls
(``signal.sosfilt``). Plain numpy, so that a component that only designs or streams a filter
does not import ``scipy.signal``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["MIN_CUTOFF_RATIO", "butterworth_sos", "sos_filter", "sos_step_state"]

FloatArray = NDArray[np.float64]

#: The smallest cutoff, as a fraction of the sample rate, whose sections float64 holds: a
#: biquad's DC gain divides by ``1 + a1 + a2``, about ``(π fc / fs)²`` computed from terms
#: near 1, so its relative error grows as ``1e-16 (fs / fc)²``; at 1e-5 it is about 1e-6,
#: and below about 1e-8 the gain (and the filtered force) becomes NaN.
MIN_CUTOFF_RATIO = 1e-5
#: Inputs longer than this are filtered by scipy's compiled sosfilt, shorter ones in Python.
_PYTHON_FILTER_MAX = 256


def butterworth_sos(cutoff_hz: float, sample_rate_hz: float, order: int) -> FloatArray:
    """Second-order sections of a digital low-pass Butterworth filter.

    The analog prototype's poles ``exp(iπ(2k + N + 1)/(2N))`` are scaled to the pre-warped
    cutoff ``2 fs tan(π fc / fs)`` and mapped by the bilinear transform; all zeros sit at
    z = −1. Conjugate pole pairs make biquads, an odd order adds one first-order section,
    and sections are ordered with the poles nearest the unit circle last (the overall gain
    rides on the first section), as ``scipy.signal.butter(..., output="sos")`` does: the
    same coefficients to a few units in the last place (``scipy.signal.butter`` is the
    reference of its tests). Written in numpy so that building a filter does not import
    ``scipy.signal`` (about 0.6 s).

    Returns
    -------
    (ceil(order / 2), 6) float64
        Rows ``[b0, b1, b2, 1, a1, a2]``.
    """
    if not 0 < cutoff_hz < sample_rate_hz / 2:
        raise ValueError(
            f"cutoff {cutoff_hz} Hz must lie between 0 and the Nyquist frequency "
            f"{sample_rate_hz / 2} Hz"
        )
    if cutoff_hz < MIN_CUTOFF_RATIO * sample_rate_hz:
        raise ValueError(
            f"cutoff {cutoff_hz:.4g} Hz is below {MIN_CUTOFF_RATIO:g} of the sample rate "
            f"({sample_rate_hz:.4g} Hz): the filter's coefficients lose their precision in "
            f"float64; the smallest cutoff is {MIN_CUTOFF_RATIO * sample_rate_hz:.4g} Hz"
        )
    n = int(order)
    if n < 1:
        raise ValueError(f"filter order must be at least 1, got {order}")
    fs2 = 2.0 * float(sample_rate_hz)
    warped = fs2 * np.tan(np.pi * float(cutoff_hz) / float(sample_rate_hz))
    analog = warped * -np.exp(1j * np.pi * np.arange(-n + 1, n, 2) / (2 * n))
    digital = (fs2 + analog) / (fs2 - analog)
    gain = float(np.real(warped**n / np.prod(fs2 - analog)))
    # One representative per conjugate pair (upper half plane), plus the real pole if any.
    pairs = sorted((p for p in digital if p.imag > 1e-12 * abs(p)), key=abs)
    real = [p.real for p in digital if abs(p.imag) <= 1e-12 * abs(p)]
    sections = [[1.0, 1.0, 0.0, 1.0, -r, 0.0] for r in real]
    sections += [[1.0, 2.0, 1.0, 1.0, -2.0 * p.real, abs(p) ** 2] for p in pairs]
    sos = np.array(sections, dtype=np.float64)
    sos[0, :3] *= gain
    return sos


def sos_step_state(sos: ArrayLike) -> FloatArray:
    """``(sections, 2)`` filter state at rest on a unit input (``scipy.signal.sosfilt_zi``).

    For the transposed direct form II of each section, a constant input ``x`` with output
    ``y = g x`` (``g`` the section's DC gain) leaves ``z2 = b2 x − a2 y`` and
    ``z1 = b1 x − a1 y + z2``; the input of each section is the output of the previous one.
    """
    s = np.asarray(sos, dtype=np.float64).reshape(-1, 6)
    state = np.empty((s.shape[0], 2))
    level = 1.0
    for k, (b0, b1, b2, _, a1, a2) in enumerate(s):
        out = level * (b0 + b1 + b2) / (1.0 + a1 + a2)
        state[k, 1] = b2 * level - a2 * out
        state[k, 0] = b1 * level - a1 * out + state[k, 1]
        level = out
    return state


def sos_filter(
    sos: ArrayLike, values: ArrayLike, state: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Run second-order sections over ``values`` from ``state``; returns (output, new state).

    Plain-float recursion (transposed direct form II), so a stream fed one sample per call
    costs microseconds and no ``scipy.signal`` import; long inputs go through
    ``scipy.signal.sosfilt`` (same recursion, compiled), imported only then.
    """
    x = np.asarray(values, dtype=np.float64).reshape(-1)
    s = np.asarray(sos, dtype=np.float64).reshape(-1, 6)
    z = np.array(state, dtype=np.float64).reshape(s.shape[0], 2)
    if x.size > _PYTHON_FILTER_MAX:
        from scipy import signal

        out, z = signal.sosfilt(s, x, zi=z)
        return out, z
    coefficients = [tuple(float(c) for c in row) for row in s]
    registers = [[float(a), float(b)] for a, b in z]
    out = np.empty(x.size)
    for i, sample in enumerate(x.tolist()):
        for (b0, b1, b2, _, a1, a2), reg in zip(coefficients, registers, strict=True):
            y = b0 * sample + reg[0]
            reg[0] = b1 * sample - a1 * y + reg[1]
            reg[1] = b2 * sample - a2 * y
            sample = y
        out[i] = sample
    return out, np.array(registers, dtype=np.float64)
