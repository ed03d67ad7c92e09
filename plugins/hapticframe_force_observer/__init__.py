"""Force observer (thesis Eq. 3.10): the environment force at a wrist force/torque sensor.

Registers the feature extractor ``force-observer``. Importing this package is cheap; the
extractor (scipy) and the fitting functions load on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

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

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
