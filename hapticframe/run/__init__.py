"""Running an experiment: assembly, the session, the dataflow and its streams, the loop, the
robot team, safety, scoring, results and training.

Imports only the kernel and :mod:`hapticframe.devices`; :mod:`hapticframe.record` and everything
above it build on this package.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe._lazy import lazy_exports

_EXPORTS = {
    "RunSummary": "hapticframe.run._results",
    "run_experiment": "hapticframe.run._run",
    "train_experiment": "hapticframe.run._train",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:
    from hapticframe.run._results import RunSummary as RunSummary
    from hapticframe.run._run import run_experiment as run_experiment
    from hapticframe.run._train import train_experiment as train_experiment
