"""Distance, direction and depth of a buried object from a raking tool's tactile forces.

Real data: the 100 trials of Chen, Versace & Jamone (IROS 2024), shipped in ``data/``
(MIT licence, ``data/SOURCE.md``), their trained Keras LSTMs read with h5py
(:func:`load_keras_model`), and a multi-head estimator trained here.
"""

from __future__ import annotations

from ._data import (
    DEPTH_CLASSES,
    DIRECTION_CLASSES,
    INPUT_SETS,
    RakingTrial,
    data_path,
    load_trials,
    select_inputs,
    windows,
)
from ._keras import KerasModelError, KerasSequential, load_keras_model, strip_keras_model
from ._lstm import DenseLayer, LSTMLayer, sigmoid, softmax

__all__ = [
    "DEPTH_CLASSES",
    "DIRECTION_CLASSES",
    "INPUT_SETS",
    "DenseLayer",
    "KerasModelError",
    "KerasSequential",
    "LSTMLayer",
    "RakingTrial",
    "data_path",
    "load_keras_model",
    "load_trials",
    "select_inputs",
    "sigmoid",
    "softmax",
    "strip_keras_model",
    "windows",
]
