"""Sweeps: an experiment's knobs varied over seeded trials, with Pareto fronts of accuracy
against wall and CPU time (``hapticframe sweep``; docs/sweeps.md).

Builds on :mod:`hapticframe.run`; only the CLI imports it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from hapticframe._lazy import lazy_exports

_EXPORTS = {
    "pareto_front": "hapticframe.sweep._sweep",
    "run_sweep": "hapticframe.sweep._sweep",
}
__all__ = sorted(_EXPORTS)
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:
    from hapticframe.sweep._sweep import pareto_front as pareto_front
    from hapticframe.sweep._sweep import run_sweep as run_sweep
