"""The streaming GRU step compiled with numba: :mod:`._step`'s numpy equations, as loops.

Imported by :mod:`._step` only when a compiled step is built, so importing the plugin never
loads numba. Compiled code is cached on disk (``cache=True``): the first step in a fresh
environment compiles for a few seconds, later processes load the cache. Plain loops (no
BLAS): at these sizes a call into BLAS costs more than the products themselves.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["sfrnn_step", "stack_step"]

FloatArray = NDArray[np.float64]


@njit(cache=True, nogil=True)
def _affine_t(w_t: FloatArray, b: FloatArray, x: FloatArray, out: FloatArray) -> None:
    """``out = w_t.T @ x + b`` as axpy over the rows of ``w_t`` (in, out).

    Row by row the inner loop has no reduction, so it vectorises without reordering any
    sum; zero inputs (most of a sparse code) are skipped, which changes nothing.
    """
    n_out = out.shape[0]
    for j in range(n_out):
        out[j] = b[j]
    for i in range(x.shape[0]):
        xi = x[i]
        if xi == 0.0:
            continue
        row = w_t[i]
        for j in range(n_out):
            out[j] += row[j] * xi


@njit(cache=True, nogil=True)
def stack_step(
    x: FloatArray, w_ih0_t: FloatArray, w_ih_rest_t: FloatArray, w_hh_t: FloatArray,
    b_ih: FloatArray, b_hh: FloatArray, h: FloatArray, gi: FloatArray, gh: FloatArray,
) -> FloatArray:
    """One step of a GRU stack: updates ``h`` (L, H) in place and returns its top row.

    Weights come transposed (``w_ih0_t`` (in, 3H), ``w_ih_rest_t`` (L-1, H, 3H),
    ``w_hh_t`` (L, H, 3H)); ``gi`` and ``gh`` are scratch of 3H values. PyTorch's
    equations, gates r, z, n: ``n = tanh(W_in x + b_in + r * (W_hn h + b_hn))``,
    ``h' = (1 - z) n + z h``; the sigmoid as ``(1 + tanh(v / 2)) / 2``, which cannot
    overflow.
    """
    layers = w_hh_t.shape[0]
    units = w_hh_t.shape[1]
    inp = x
    for layer in range(layers):
        if layer == 0:
            _affine_t(w_ih0_t, b_ih[0], inp, gi)
        else:
            _affine_t(w_ih_rest_t[layer - 1], b_ih[layer], inp, gi)
        _affine_t(w_hh_t[layer], b_hh[layer], h[layer], gh)
        for j in range(units):
            r = 0.5 * (1.0 + np.tanh(0.5 * (gi[j] + gh[j])))
            z = 0.5 * (1.0 + np.tanh(0.5 * (gi[units + j] + gh[units + j])))
            n = np.tanh(gi[2 * units + j] + r * gh[2 * units + j])
            h[layer, j] = (1.0 - z) * n + z * h[layer, j]
        inp = h[layer]
    return inp


@njit(cache=True, nogil=True)
def sfrnn_step(
    x: FloatArray, fusion_w_t: FloatArray, fusion_b: FloatArray, w_ih0_t: FloatArray,
    w_ih_rest_t: FloatArray, w_hh_t: FloatArray, b_ih: FloatArray, b_hh: FloatArray,
    readout_w: FloatArray, readout_b: FloatArray, h: FloatArray, logits: FloatArray,
    fused: FloatArray, gi: FloatArray, gh: FloatArray,
) -> None:
    """One SF-RNN frame: ReLU fusion layer, :func:`stack_step`, linear read-out into ``logits``.

    ``fused`` (fusion units) and ``gi``/``gh`` (3H) are scratch.
    """
    _affine_t(fusion_w_t, fusion_b, x, fused)
    for j in range(fused.shape[0]):
        if fused[j] < 0.0:
            fused[j] = 0.0
    top = stack_step(fused, w_ih0_t, w_ih_rest_t, w_hh_t, b_ih, b_hh, h, gi, gh)
    for k in range(readout_w.shape[0]):
        a = readout_b[k]
        for i in range(top.shape[0]):
            a += readout_w[k, i] * top[i]
        logits[k] = a
