"""A numpy LSTM and dense layer, float64, with the gate algebra Keras and torch share.

Both libraries compute, per step, ``z = x W + h U + b`` split into four gates in the order
input, forget, cell, output (Keras ``LSTM`` with ``activation='tanh'`` and
``recurrent_activation='sigmoid'``; torch ``nn.LSTM``, whose two biases add up to ``b``):
``c' = σ(f) c + σ(i) tanh(g)``, ``h' = σ(o) tanh(c')``. The logistic function is computed as
``(1 + tanh(x / 2)) / 2``, which never overflows.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["DenseLayer", "LSTMLayer", "sigmoid", "softmax"]

FloatArray = NDArray[np.float64]


def sigmoid(x: FloatArray) -> FloatArray:
    """The logistic function, without overflow for any finite input."""
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def softmax(x: FloatArray) -> FloatArray:
    """Softmax over the last axis (shifted by the maximum: no overflow)."""
    shifted = x - x.max(axis=-1, keepdims=True)
    e = np.exp(shifted)
    out: FloatArray = e / e.sum(axis=-1, keepdims=True)
    return out


@dataclass(frozen=True)
class LSTMLayer:
    """One LSTM layer: ``kernel (d, 4u)``, ``recurrent (u, 4u)``, ``bias (4u,)``."""

    kernel: FloatArray
    recurrent: FloatArray
    bias: FloatArray

    def __post_init__(self) -> None:
        k = np.asarray(self.kernel, dtype=np.float64)
        r = np.asarray(self.recurrent, dtype=np.float64)
        b = np.asarray(self.bias, dtype=np.float64).reshape(-1)
        units = r.shape[0]
        if k.ndim != 2 or r.shape != (units, 4 * units) or k.shape[1] != 4 * units or (
                b.shape != (4 * units,)):
            raise ValueError(f"LSTM weights do not fit: kernel {k.shape}, recurrent {r.shape}, "
                             f"bias {b.shape}")
        object.__setattr__(self, "kernel", k)
        object.__setattr__(self, "recurrent", r)
        object.__setattr__(self, "bias", b)

    @property
    def units(self) -> int:
        return int(self.recurrent.shape[0])

    @property
    def input_size(self) -> int:
        return int(self.kernel.shape[0])

    def sequence(self, x: FloatArray) -> FloatArray:
        """Hidden states ``(b, T, u)`` for inputs ``(b, T, d)``, from zero state."""
        b, steps, _ = x.shape
        u = self.units
        h = np.zeros((b, u))
        c = np.zeros((b, u))
        projected = x @ self.kernel + self.bias  # every step's input part at once
        out = np.empty((b, steps, u))
        for t in range(steps):
            z = projected[:, t] + h @ self.recurrent
            i = sigmoid(z[:, :u])
            f = sigmoid(z[:, u:2 * u])
            g = np.tanh(z[:, 2 * u:3 * u])
            o = sigmoid(z[:, 3 * u:])
            c = f * c + i * g
            h = o * np.tanh(c)
            out[:, t] = h
        return out


@dataclass(frozen=True)
class DenseLayer:
    """``activation(x W + b)`` on the last axis; activation one of linear, sigmoid, softmax,
    tanh, relu."""

    kernel: FloatArray
    bias: FloatArray
    activation: str = "linear"

    def __post_init__(self) -> None:
        k = np.asarray(self.kernel, dtype=np.float64)
        b = np.asarray(self.bias, dtype=np.float64).reshape(-1)
        if k.ndim != 2 or b.shape != (k.shape[1],):
            raise ValueError(f"dense weights do not fit: kernel {k.shape}, bias {b.shape}")
        if self.activation not in _ACTIVATIONS:
            raise ValueError(f"dense activation {self.activation!r} is not one of "
                             f"{', '.join(_ACTIVATIONS)}")
        object.__setattr__(self, "kernel", k)
        object.__setattr__(self, "bias", b)

    def __call__(self, x: FloatArray) -> FloatArray:
        return _ACTIVATIONS[self.activation](x @ self.kernel + self.bias)


_ACTIVATIONS: dict[str, Callable[[FloatArray], FloatArray]] = {
    "linear": lambda z: z,
    "sigmoid": sigmoid,
    "softmax": softmax,
    "tanh": np.tanh,
    "relu": lambda z: np.maximum(z, 0.0),
}
