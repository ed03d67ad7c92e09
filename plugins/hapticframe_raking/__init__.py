"""Distance, direction and depth of a buried object from a raking tool's tactile forces.

Real data: the 100 trials of Chen, Versace & Jamone (IROS 2024), shipped in ``data/``
(MIT licence, ``data/SOURCE.md``), their trained Keras LSTMs read with h5py
(:func:`load_keras_model`), and a multi-head estimator trained here.
"""

from __future__ import annotations

from ._config import DistanceEstimateConfig, RakingEstimatorConfig
from ._data import (
    DEPTH_CLASSES,
    DIRECTION_CLASSES,
    INPUT_SETS,
    RakingTrial,
    data_path,
    jamming_labels,
    load_trials,
    object_point,
    select_inputs,
    windows,
    write_jamming_labels,
)
from ._estimator import RakingEstimator, pretrained_model_dir
from ._keras import KerasModelError, KerasSequential, load_keras_model, strip_keras_model
from ._keras_check import KERAS_TOLERANCE, keras_available, keras_check
from ._lstm import DenseLayer, LSTMLayer, sigmoid, softmax
from ._model import EstimatorSettings, ObjectEstimate, RakingModel, TrainingTrial, fit_model
from ._scoring import AuthorsModels, TrialScores, authors_models_dir, score_trials, summarize
from ._selection import (
    CV_CHOICE,
    CV_GRID,
    CV_RANGE_MM,
    SELECTED,
    cross_validate,
    selected_settings,
    trial_groups,
)
from ._sensor_model import (
    DistanceEstimateSensorModel,
    certainty_weights,
    consistency_weights,
    place_observations,
)

__all__ = [
    "CV_CHOICE",
    "CV_GRID",
    "CV_RANGE_MM",
    "DEPTH_CLASSES",
    "DIRECTION_CLASSES",
    "INPUT_SETS",
    "KERAS_TOLERANCE",
    "AuthorsModels",
    "DenseLayer",
    "DistanceEstimateConfig",
    "DistanceEstimateSensorModel",
    "EstimatorSettings",
    "KerasModelError",
    "KerasSequential",
    "LSTMLayer",
    "ObjectEstimate",
    "RakingEstimator",
    "RakingEstimatorConfig",
    "RakingModel",
    "RakingTrial",
    "SELECTED",
    "TrainingTrial",
    "TrialScores",
    "authors_models_dir",
    "certainty_weights",
    "consistency_weights",
    "cross_validate",
    "data_path",
    "fit_model",
    "jamming_labels",
    "keras_available",
    "keras_check",
    "load_keras_model",
    "load_trials",
    "object_point",
    "place_observations",
    "pretrained_model_dir",
    "score_trials",
    "select_inputs",
    "selected_settings",
    "sigmoid",
    "softmax",
    "strip_keras_model",
    "summarize",
    "trial_groups",
    "windows",
    "write_jamming_labels",
]
