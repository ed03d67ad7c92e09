"""Batch-1 streaming inference of the recurrent networks, without torch on the hot path.

A 4 × 50 GRU step at batch 1 is a handful of 150 × 50 matrix-vector products: tens of
microseconds of arithmetic. Stepping the SF-RNN's torch network costs ≈ 0.2–0.3 ms per frame
(a plain 4 × 50 ``torch.nn.GRU`` ≈ 0.12 ms), nearly all of it per-call overhead (module
dispatch, one tensor per layer and gate); the compiled step below ≈ 15–25 µs.
:class:`StreamingStep` copies a trained :class:`~._networks.RecurrentNet`'s weights once
into float64 numpy arrays and runs the same recurrence (PyTorch's GRU equations, gate order
r, z, n) one frame at a time: one compiled call per frame with numba (``learn`` installs
it; compiled code is cached on disk), the same equations in numpy without it.

Training stays in torch; this is the evaluation-mode forward only (no dropout). Computing
in float64 with the float32 weights makes it *more* exact than torch's float32 step, not
less: the two agree to about 1e-7 (tests hold them to 1e-6 over long streams, and to 1e-12
against the same network run by torch in float64).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import torch
from numpy.typing import NDArray

from ._networks import FusionRNNNet, GRUStack, RecurrentNet, SFRNNNet

__all__ = ["GRUStackWeights", "StreamingStep", "numba_available", "step_backend_in_use"]

FloatArray = NDArray[np.float64]


def numba_available() -> bool:
    """Whether the compiled step can run (numba is installed; checked without importing)."""
    return importlib.util.find_spec("numba") is not None


def step_backend_in_use(backend: str = "auto") -> str:
    """What ``backend`` resolves to: ``"numba"`` or ``"numpy"``."""
    if backend not in ("auto", "numba", "numpy"):
        raise ValueError(f"backend must be 'auto', 'numba' or 'numpy', got {backend!r}")
    if backend == "numba" and not numba_available():
        raise ImportError("backend='numba' needs numba: pip install 'numba>=0.60'")
    if backend == "auto":
        return "numba" if numba_available() else "numpy"
    return backend


def _array(tensor: torch.Tensor | torch.nn.Module) -> FloatArray:
    # A GRU's weights are typed Tensor | Module by torch's stubs (module attributes).
    return np.ascontiguousarray(cast(torch.Tensor, tensor).detach().cpu().numpy(),
                                dtype=np.float64)


@dataclass(frozen=True)
class GRUStackWeights:
    """One :class:`~._networks.GRUStack`'s weights in float64, laid out for the step kernel.

    ``w_ih0`` (3H, in) is the first layer's input matrix; ``w_ih_rest`` (L-1, 3H, H) the
    others' (empty for one layer); ``w_hh`` (L, 3H, H), ``b_ih`` and ``b_hh`` (L, 3H).
    ``t_ih0``, ``t_ih_rest`` and ``t_hh`` are the matrices transposed (contiguous), as the
    compiled kernel reads them.
    """

    w_ih0: FloatArray
    w_ih_rest: FloatArray
    w_hh: FloatArray
    b_ih: FloatArray
    b_hh: FloatArray
    t_ih0: FloatArray
    t_ih_rest: FloatArray
    t_hh: FloatArray

    @classmethod
    def of(cls, stack: GRUStack) -> GRUStackWeights:
        grus = [cast(torch.nn.GRU, g) for g in stack.layers]
        units = stack.units
        rest = [_array(g.weight_ih_l0) for g in grus[1:]]
        w_ih0 = _array(grus[0].weight_ih_l0)
        w_ih_rest = np.stack(rest) if rest else np.zeros((0, 3 * units, units))
        w_hh = np.stack([_array(g.weight_hh_l0) for g in grus])
        return cls(
            w_ih0=w_ih0,
            w_ih_rest=w_ih_rest,
            w_hh=w_hh,
            b_ih=np.stack([_array(g.bias_ih_l0) for g in grus]),
            b_hh=np.stack([_array(g.bias_hh_l0) for g in grus]),
            t_ih0=np.ascontiguousarray(w_ih0.T),
            t_ih_rest=np.ascontiguousarray(w_ih_rest.transpose(0, 2, 1)),
            t_hh=np.ascontiguousarray(w_hh.transpose(0, 2, 1)),
        )

    @property
    def layers(self) -> int:
        return int(self.w_hh.shape[0])

    @property
    def units(self) -> int:
        return int(self.w_hh.shape[2])

    def initial_state(self) -> FloatArray:
        return np.zeros((self.layers, self.units))


# -- numpy reference ----------------------------------------------------------------------


def _sigmoid(v: FloatArray) -> FloatArray:
    # The tanh form never overflows (exp(-v) would for v < -709) and is what the kernel uses.
    return 0.5 * (1.0 + np.tanh(0.5 * v))


def stack_step_numpy(x: FloatArray, w: GRUStackWeights, h: FloatArray) -> FloatArray:
    """One GRU-stack step in numpy: updates ``h`` (L, H) in place, returns the top output."""
    units = w.units
    inp = x
    for layer in range(w.layers):
        w_ih = w.w_ih0 if layer == 0 else w.w_ih_rest[layer - 1]
        gi = w_ih @ inp + w.b_ih[layer]
        gh = w.w_hh[layer] @ h[layer] + w.b_hh[layer]
        r = _sigmoid(gi[:units] + gh[:units])
        z = _sigmoid(gi[units : 2 * units] + gh[units : 2 * units])
        n = np.tanh(gi[2 * units :] + r * gh[2 * units :])
        h[layer] = (1.0 - z) * n + z * h[layer]
        inp = h[layer]
    return inp


def _sfrnn_step_numpy(
    x: FloatArray, fusion_w: FloatArray, fusion_b: FloatArray, w: GRUStackWeights,
    readout_w: FloatArray, readout_b: FloatArray, h: FloatArray, logits: FloatArray,
) -> None:
    fused = np.maximum(fusion_w @ x + fusion_b, 0.0)
    top = stack_step_numpy(fused, w, h)
    logits[:] = readout_w @ top + readout_b


# -- compiled kernels (imported on first use; numba caches them on disk) ----------------

_KERNELS: dict[str, Callable[..., Any]] = {}


def _kernels() -> dict[str, Callable[..., Any]]:
    """The numba kernels of :mod:`._step_kernel`, imported (so compiled or loaded) once."""
    if not _KERNELS:
        from ._step_kernel import sfrnn_step, stack_step

        _KERNELS.update(sfrnn_step=sfrnn_step, stack_step=stack_step)
    return _KERNELS


# -- the step of a whole network ----------------------------------------------------------


class StreamingStep:
    """The evaluation-mode forward of ``net`` for one frame at a time, in float64.

    Parameters
    ----------
    net : SFRNNNet or FusionRNNNet
        Its weights are copied now; build a new step after changing them.
    backend : {"auto", "numba", "numpy"}
        ``"auto"`` takes the compiled kernel when numba is installed.

    Notes
    -----
    The state is a list of (layers, units) float64 arrays, one per GRU stack (SF-RNN: one;
    Fusion RNN: one per modality), updated in place by :meth:`step`.
    """

    def __init__(self, net: RecurrentNet, backend: str = "auto") -> None:
        self.backend = step_backend_in_use(backend)
        self._kernels = _kernels() if self.backend == "numba" else {}
        self.sfrnn = isinstance(net, SFRNNNet)
        if isinstance(net, SFRNNNet):
            self.stacks = [GRUStackWeights.of(net.gru)]
            self.fusion_w, self.fusion_b = _array(net.fusion.weight), _array(net.fusion.bias)
        elif isinstance(net, FusionRNNNet):
            self.stacks = [GRUStackWeights.of(cast(GRUStack, b)) for b in net.branches]
            self.fusion_w, self.fusion_b = _array(net.fusion.weight), _array(net.fusion.bias)
        else:
            raise TypeError(f"no streaming step for {type(net).__name__}")
        self.fusion_w_t = np.ascontiguousarray(self.fusion_w.T)
        self.readout_w, self.readout_b = _array(net.readout.weight), _array(net.readout.bias)
        self.group_sizes = list(net.group_sizes)
        self.n_classes = int(self.readout_w.shape[0])
        # Scratch for the kernels, allocated once rather than every frame.
        widest = max(3 * s.units for s in self.stacks)
        self._gi, self._gh = np.empty(widest), np.empty(widest)
        self._fused = np.empty(self.fusion_w.shape[0])

    def initial_state(self) -> list[FloatArray]:
        """Zero hidden states, as ``net.initial_state(1)``."""
        return [s.initial_state() for s in self.stacks]

    def step(self, x: FloatArray, state: list[FloatArray], logits: FloatArray) -> None:
        """Advance ``state`` by one frame of inputs ``x`` (d,) and write the logits (k,).

        ``x`` must be float64 and contiguous (already scaled, as the network expects).
        """
        if self.sfrnn:
            w = self.stacks[0]
            if self.backend == "numba":
                self._kernels["sfrnn_step"](
                    x, self.fusion_w_t, self.fusion_b, w.t_ih0, w.t_ih_rest, w.t_hh, w.b_ih,
                    w.b_hh, self.readout_w, self.readout_b, state[0], logits, self._fused,
                    self._gi[: 3 * w.units], self._gh[: 3 * w.units])
            else:
                _sfrnn_step_numpy(x, self.fusion_w, self.fusion_b, w, self.readout_w,
                                  self.readout_b, state[0], logits)
            return
        outputs, col = [], 0
        for w, h, size in zip(self.stacks, state, self.group_sizes, strict=True):
            part = x[col : col + size]
            if self.backend == "numba":
                gi, gh = self._gi[: 3 * w.units], self._gh[: 3 * w.units]
                outputs.append(self._kernels["stack_step"](
                    part, w.t_ih0, w.t_ih_rest, w.t_hh, w.b_ih, w.b_hh, h, gi, gh).copy())
            else:
                outputs.append(stack_step_numpy(part, w, h).copy())
            col += size
        fused = np.maximum(self.fusion_w @ np.concatenate(outputs) + self.fusion_b, 0.0)
        logits[:] = self.readout_w @ fused + self.readout_b
