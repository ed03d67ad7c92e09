"""Contact-state classifiers of the BioTac pipeline (dissertation §2.4.2, §2.7, App. A.3).

Registers ``sf-rnn`` (sparse codes → fusion layer → stacked GRU), ``fusion-rnn`` (one GRU
per modality joined by a fully connected layer) and ``linear-svm`` (Platt-calibrated
linear SVM on any flattened channels). Importing this package is cheap: torch and
scikit-learn load on first attribute access of the classes that need them.

Besides the components, the package offers the scores its classifiers are judged by
(:func:`balanced_accuracy`, :func:`contact_figures`); the perception benchmark
(``hapticframe bench perception``, in ``hapticframe_bench``) uses them.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import CLASSES, FusionRNNConfig, LinearSVMConfig, SFRNNConfig

__all__ = [
    "CLASSES",
    "FusionRNNClassifier",
    "FusionRNNConfig",
    "LinearSVMClassifier",
    "LinearSVMConfig",
    "SFRNNClassifier",
    "SFRNNConfig",
    "balanced_accuracy",
    "contact_figures",
]

_LAZY = {
    "SFRNNClassifier": "._recurrent",
    "FusionRNNClassifier": "._recurrent",
    "LinearSVMClassifier": "._linear_svm",
    "balanced_accuracy": "._functional",
    "contact_figures": "._functional",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
