"""A world whose sand is simulated by an independent engine: NVIDIA Newton's implicit
material-point solver (issue 29).

Registers the robot ``mpm-sand`` (the sandbox robot holding an :class:`MpmSandWorld`, read by
the ``sandbox-force`` sensor) and the benchmark
``physics-checks``. The world runs from a response library of engine runs stored in
``data/`` (plain arrays): running it needs numpy only; building a library or running the
checks needs the ``physics`` extra (``newton``). See docs/physics-world.md.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import MpmSandRobotConfig
from ._library import ResponseLibrary, fit_power_law, load_library, save_library

__all__ = [
    "MpmSandRobot",
    "MpmSandRobotConfig",
    "MpmSandWorld",
    "ResponseLibrary",
    "bundled_library",
    "engine_available",
    "fit_power_law",
    "load_library",
    "save_library",
]

_LAZY = {
    "MpmSandRobot": "._world",
    "MpmSandWorld": "._world",
    "bundled_library": "._world",
    "engine_available": "._engine",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
