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

import importlib
from typing import Any

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


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
