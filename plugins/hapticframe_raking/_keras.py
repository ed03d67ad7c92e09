"""The authors' trained Keras models, read from their HDF5 files with h5py alone.

A Keras 2 ``model.save('x.h5')`` file holds the model's configuration as JSON
(``attrs['model_config']``) and each layer's weights under ``model_weights/<layer>/`` in
the order ``attrs['weight_names']`` lists. :func:`load_keras_model` reads a ``Sequential``
of ``LSTM`` and ``Dense`` layers, checks every setting the numpy forward pass relies on
(tanh and sigmoid gates, no stateful or backwards LSTM, every layer returning sequences as
the authors' ``train_main.py`` builds them) and refuses anything else. Nothing in the file
is executed: a Keras ``Lambda`` layer is refused, not run.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.bounded_io import BoundedReadError, hdf5_child, open_hdf5, read_hdf5_dataset

from ._lstm import DenseLayer, LSTMLayer

__all__ = ["MAX_WEIGHT_VALUES", "KerasModelError", "KerasSequential", "load_keras_model",
           "strip_keras_model"]

#: Weights one model file may hold in all (the authors' models hold about 10^4).
MAX_WEIGHT_VALUES = 16_000_000


class KerasModelError(ValueError):
    """A Keras HDF5 file that cannot be read, or holds what the numpy forward cannot run."""


@dataclass(frozen=True)
class KerasSequential:
    """A Sequential of LSTM and Dense layers, run in float64 numpy.

    ``layers`` in order; ``input_shape`` is ``(steps, features)`` as the model was built.
    """

    layers: tuple[LSTMLayer | DenseLayer, ...]
    input_shape: tuple[int | None, int]
    source: str

    def describe(self) -> list[str]:
        """One line per layer: type, units and activation, as ``train_main.py`` names them."""
        out = []
        for layer in self.layers:
            if isinstance(layer, LSTMLayer):
                out.append(f"LSTM(units={layer.units}, return_sequences=True)")
            else:
                out.append(f"Dense(units={layer.kernel.shape[1]}, "
                           f"activation='{layer.activation}')")
        return out

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Outputs ``(b, T, k)`` for windows ``(b, T, d)`` (every layer returns sequences)."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim != 3 or x.shape[2] != self.input_shape[1]:
            raise ValueError(f"{self.source}: expects windows (b, T, {self.input_shape[1]}), "
                             f"got {x.shape}")
        for layer in self.layers:
            x = layer.sequence(x) if isinstance(layer, LSTMLayer) else layer(x)
        return x


def _text(value: Any) -> str:
    return value.decode("utf-8") if isinstance(value, bytes) else str(value)


def _weights(group: Any, source: str, name: str, budget: list[int]
             ) -> list[NDArray[np.float64]]:
    import h5py

    names = [_text(n) for n in group.attrs.get("weight_names", [])]
    if not names:
        raise KerasModelError(f"{source}: layer {name!r} lists no weights")
    out = []
    for weight in names:
        node = hdf5_child(group, weight)
        if not isinstance(node, h5py.Dataset):
            raise KerasModelError(f"{source}: layer {name!r} lacks weight {weight!r}")
        values = read_hdf5_dataset(node, budget[0], kinds="f")
        budget[0] -= values.size
        array = np.asarray(values, dtype=np.float64)
        if not np.all(np.isfinite(array)):
            raise KerasModelError(f"{source}: {node.name} holds NaN or infinite weights")
        out.append(array)
    return out


def _check(source: str, name: str, config: dict[str, Any], expected: dict[str, Any]) -> None:
    for key, want in expected.items():
        if key in config and config[key] != want:
            raise KerasModelError(f"{source}: layer {name!r} has {key}={config[key]!r}; the "
                                  f"numpy forward needs {want!r}")


def load_keras_model(path: str | Path) -> KerasSequential:
    """Read a Keras 2 HDF5 Sequential of LSTM and Dense layers (see the module docstring).

    Raises
    ------
    KerasModelError
        Naming the file: missing, not a regular HDF5 file, damaged (a link outside the
        file, a dangling one, raw data stored outside it, more than
        :data:`MAX_WEIGHT_VALUES` weights), or a model the numpy forward cannot run.
    """
    source = str(path)
    try:
        handle = open_hdf5(path)
    except FileNotFoundError:
        raise KerasModelError(f"{source}: no such file") from None
    except BoundedReadError as exc:
        raise KerasModelError(f"{source}: {exc}") from None
    with handle:
        try:
            return _read_model(handle, source)
        except BoundedReadError as exc:
            raise KerasModelError(f"{source}: {exc}") from None
        except (KeyError, TypeError, IndexError, AttributeError, ValueError, RecursionError,
                OSError, RuntimeError) as exc:
            if isinstance(exc, KerasModelError):
                raise
            # A model_config of another structure, or h5py on a damaged attribute.
            raise KerasModelError(f"{source}: not a Keras model this reader understands "
                                  f"({type(exc).__name__}: {str(exc)[:200]})") from None


def _read_model(handle: Any, source: str) -> KerasSequential:
    import h5py

    if "model_config" not in handle.attrs:
        raise KerasModelError(f"{source}: not a Keras model file (no model_config or "
                              "model_weights)")
    try:
        config = json.loads(_text(handle.attrs["model_config"]))
    except json.JSONDecodeError as exc:
        raise KerasModelError(f"{source}: model_config is not JSON ({exc})") from None
    if config.get("class_name") != "Sequential":
        raise KerasModelError(f"{source}: a {config.get('class_name')!r} model; only "
                              "Sequential is read")
    layers: list[LSTMLayer | DenseLayer] = []
    input_shape: tuple[int | None, int] | None = None
    weights = hdf5_child(handle, "model_weights")
    if not isinstance(weights, h5py.Group):
        raise KerasModelError(f"{source}: not a Keras model file (no model_weights group)")
    budget = [MAX_WEIGHT_VALUES]
    for entry in config["config"]["layers"]:
        kind, cfg = entry["class_name"], entry["config"]
        name = cfg.get("name", "?")
        shape = cfg.get("batch_input_shape")
        if shape is not None and input_shape is None:
            input_shape = (shape[1], int(shape[2]))
        if kind == "InputLayer":
            continue
        group = hdf5_child(weights, str(name))
        if not isinstance(group, h5py.Group):
            raise KerasModelError(f"{source}: no weights for layer {name!r}")
        w = _weights(group, source, name, budget)
        if kind == "LSTM":
            _check(source, name, cfg, {
                "activation": "tanh", "recurrent_activation": "sigmoid", "use_bias": True,
                "go_backwards": False, "stateful": False, "time_major": False,
                "return_sequences": True})
            layers.append(LSTMLayer(*w))
        elif kind == "Dense":
            _check(source, name, cfg, {"use_bias": True})
            layers.append(DenseLayer(w[0], w[1], cfg.get("activation", "linear")))
        else:
            raise KerasModelError(f"{source}: layer {name!r} is a {kind}; only LSTM and "
                                  "Dense are read")
    if input_shape is None or not layers:
        raise KerasModelError(f"{source}: no input shape or no layers")
    _chain(layers, input_shape[1], source)
    return KerasSequential(tuple(layers), input_shape, source)


def _chain(layers: Sequence[LSTMLayer | DenseLayer], features: int, source: str) -> None:
    width = features
    for layer in layers:
        if layer.kernel.shape[0] != width:
            raise KerasModelError(f"{source}: a layer takes {layer.kernel.shape[0]} inputs "
                                  f"after one of {width}")
        width = layer.units if isinstance(layer, LSTMLayer) else layer.kernel.shape[1]


def strip_keras_model(source: str | Path, target: str | Path) -> None:
    """Copy a Keras HDF5 model without its optimizer state (configuration and weights only).

    The weights are copied bit for bit; the file stays loadable by Keras
    (``load_model(..., compile=False)``) and by :func:`load_keras_model`.
    """
    import h5py

    with h5py.File(source, "r") as src, h5py.File(target, "w") as dst:
        for key in ("model_config", "keras_version", "backend"):
            if key in src.attrs:
                dst.attrs[key] = src.attrs[key]
        src_w = src["model_weights"]
        dst_w = dst.create_group("model_weights")
        for key, value in src_w.attrs.items():
            dst_w.attrs[key] = value
        for layer in src_w:
            group = dst_w.create_group(layer)
            for key, value in src_w[layer].attrs.items():
                group.attrs[key] = value
            for name in [_text(n) for n in src_w[layer].attrs.get("weight_names", [])]:
                group.create_dataset(name, data=np.asarray(src_w[layer][name]),
                                     compression="gzip", compression_opts=9)
