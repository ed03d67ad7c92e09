"""The numpy port of the authors' models checked against Keras itself (the ``keras`` extra).

Keras 3 does not load the authors' Keras 2 HDF5 files: their LSTM configs carry
``time_major``, an argument Keras 3 no longer takes (``load_model`` raises). So each model
is built as the authors' ``train_main.py`` builds it (``Sequential`` of ``LSTM(20)`` and a
softmax or sigmoid ``Dense`` for direction and depth; ``LSTM(100)``, ``LSTM(50)`` and a
linear ``Dense(1)`` for distance), and Keras's own legacy HDF5 reader sets its weights
(``Model.load_weights``: by layer order, independent of our h5py reader). Then

- the whole model in float64, and layer by layer (each Keras layer in float64 fed the
  port's previous layer's output), against :class:`~hapticframe_raking.KerasSequential`
  (float64) on the same windows: the check, to :data:`KERAS_TOLERANCE`; and
- the whole model as the authors ran it (``predict`` in float32), reported beside it: it
  differs by float32 rounding (a few 1e-6 on probabilities), not by the port.

The difference is measured relative to the output's size: ``|port − keras| / max(1,
|keras|)`` (absolute for probabilities, relative for a distance in mm). Keras 3 computes a
``Dense`` layer's product in float32 even in a float64 model (its type promotion turns
64-bit results into 32-bit ones, as JAX does by default), so a float64 ``Dense`` agrees to
float32 rounding only; its LSTM layers agree to float64 rounding.
"""

from __future__ import annotations

import os
import time
import warnings
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ._data import INPUT_SETS, RakingTrial, select_inputs, windows
from ._keras import load_keras_model
from ._lstm import LSTMLayer

__all__ = ["KERAS_TOLERANCE", "keras_available", "keras_check"]

#: The agreement the check asks for (relative to max(1, |output|)).
KERAS_TOLERANCE = 1e-6
_TASKS = ("direction", "depth", "distance")


def keras_available() -> str | None:
    """``None`` when Keras 3 imports on the torch backend, else why not."""
    os.environ.setdefault("KERAS_BACKEND", "torch")
    try:
        import keras
    except ImportError as exc:
        return f"keras is not installed ({exc}; pip install 'hapticframe[keras]')"
    if not keras.__version__.startswith("3"):
        return f"keras {keras.__version__} is not Keras 3"
    return None


def _build(task: str, features: int, dtype: str) -> Any:
    """The model ``train_main.py`` builds for ``task`` (``input_shape=(5, features)``)."""
    import keras

    layers: list[Any] = [keras.Input((5, features), dtype=dtype)]
    if task == "distance":
        layers += [keras.layers.LSTM(100, return_sequences=True, dtype=dtype),
                   keras.layers.LSTM(50, return_sequences=True, dtype=dtype),
                   keras.layers.Dense(1, activation="linear", dtype=dtype)]
    else:
        layers += [keras.layers.LSTM(20, return_sequences=True, dtype=dtype),
                   keras.layers.Dense(3, activation="softmax", dtype=dtype)
                   if task == "direction" else
                   keras.layers.Dense(1, activation="sigmoid", dtype=dtype)]
    return keras.Sequential(layers)


def _relative(port: NDArray[np.float64], keras_out: NDArray[np.float64]) -> float:
    return float(np.max(np.abs(port - keras_out) / np.maximum(1.0, np.abs(keras_out)),
                        initial=0.0))


def _load_error(path: Path) -> str | None:
    import keras

    try:
        with warnings.catch_warnings():  # its input_shape warning is not the finding
            warnings.simplefilter("ignore")
            keras.models.load_model(path, compile=False)
    except Exception as exc:
        return f"{type(exc).__name__}: {str(exc).splitlines()[0][:200]}"
    return None


def _check_model(path: Path, task: str, x: NDArray[np.float64]) -> dict[str, Any]:
    import keras

    port = load_keras_model(path)
    started = time.perf_counter()
    whole = _build(task, x.shape[2], "float32")
    whole.load_weights(path)
    keras_out = np.asarray(whole.predict(x.astype(np.float32), batch_size=len(x), verbose=0),
                           dtype=np.float64)
    port_out = port(x)
    per_layer = _build(task, x.shape[2], "float64")
    per_layer.load_weights(path)
    whole64 = np.asarray(keras.ops.convert_to_numpy(per_layer(x)), dtype=np.float64)
    layers: list[dict[str, Any]] = []
    h = x
    for keras_layer, port_layer in zip(per_layer.layers, port.layers, strict=True):
        want = np.asarray(keras.ops.convert_to_numpy(keras_layer(h)), dtype=np.float64)
        h = port_layer.sequence(h) if isinstance(port_layer, LSTMLayer) else port_layer(h)
        layers.append({"layer": type(keras_layer).__name__,
                       "units": int(h.shape[-1]),
                       "max_relative_difference": _relative(h, want)})
    return {
        "file": path.name,
        "keras3_load_model_error": _load_error(path),
        "built_from": "train_main.py",
        "windows": len(x),
        "max_relative_difference": max([_relative(port_out, whole64)]
                                       + [float(x["max_relative_difference"]) for x in layers]),
        "whole_float64_max_abs_difference": float(np.max(np.abs(port_out - whole64))),
        "whole_float32_max_abs_difference": float(np.max(np.abs(port_out - keras_out))),
        "whole_float32_max_relative_difference": _relative(port_out, keras_out),
        "layers_float64": layers,
        "keras_s": time.perf_counter() - started,
    }


def keras_check(trials: Sequence[RakingTrial], directory: str | Path,
                input_sets: Iterable[str] = tuple(INPUT_SETS),
                tasks: Iterable[str] = _TASKS) -> dict[str, Any]:
    """Compare the port with Keras on every 5-step window of ``trials`` (see the module).

    Returns ``{"keras": version, "backend": ..., "tolerance": ..., "models": [...],
    "max_relative_difference": ..., "within_tolerance": bool}``; ``{"skipped": reason}``
    when Keras 3 is not importable.
    """
    reason = keras_available()
    if reason is not None:
        return {"skipped": reason}
    import keras

    d = Path(directory)
    models = []
    for input_set in input_sets:
        x = np.concatenate([windows(select_inputs(t.force, input_set), 5, pad=False)
                            for t in trials])
        for task in tasks:
            entry = _check_model(d / f"{input_set}_{task}_model.h5", task, x)
            models.append({"input_set": input_set, "task": task} | entry)
    worst = max((m["max_relative_difference"] for m in models), default=0.0)
    worst32 = max((m["whole_float32_max_relative_difference"] for m in models), default=0.0)
    errors = sorted({m["keras3_load_model_error"] or "loads" for m in models})
    return {"keras": keras.__version__, "backend": keras.backend.backend(),
            "tolerance": KERAS_TOLERANCE, "keras3_load_model": errors, "models": models,
            "windows": models[0]["windows"] if models else 0,
            "max_relative_difference": worst, "within_tolerance": worst <= KERAS_TOLERANCE,
            "float32_max_relative_difference": worst32}
