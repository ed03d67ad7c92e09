"""Force observer (thesis Eq. 3.10): the environment force at a wrist force/torque sensor.

Registers the feature extractor ``force-observer``. Importing this package is cheap; the
extractor (scipy) and the fitting functions load on first attribute access.
"""

from __future__ import annotations

import importlib
from typing import Any

from ._config import ForceObserverConfig

__all__ = [
    "ExcitationWarning",
    "ForceObserver",
    "ForceObserverConfig",
    "ObserverFit",
    "apply_force_observer",
    "fit_force_observer",
]

_LAZY = {
    "ExcitationWarning": "._functional",
    "ObserverFit": "._functional",
    "apply_force_observer": "._functional",
    "fit_force_observer": "._functional",
    "ForceObserver": "._observer",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
