"""Simulated sandbox: a plate raked through sand towards buried objects, and its force sensor.

Registers the robot ``sandbox`` and the sensor ``sandbox-force``. The robot's physics is a
:class:`hapticframe.kinds.World` (:class:`AnalyticSandWorld` by default; another robot type
chooses its own by overriding :meth:`SandboxRobot.build_world`). Importing this package is
cheap; the simulator classes load on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import SandboxForceSensorConfig, SandboxRobotConfig, SandboxTaxelSensorConfig

__all__ = [
    "AnalyticSandWorld",
    "GroundTruthLog",
    "MovementTruth",
    "SandboxForceSensor",
    "SandboxForceSensorConfig",
    "SandboxRobot",
    "SandboxRobotConfig",
    "SandboxTaxelSensor",
    "SandboxTaxelSensorConfig",
    "TaxelModel",
    "approach_movement",
    "fit_taxel_model",
    "force_components",
    "raking_labels",
    "record_movements",
]

_LAZY = {
    "AnalyticSandWorld": "._analytic",
    "GroundTruthLog": "._truth",
    "MovementTruth": "._truth",
    "SandboxRobot": "._robot",
    "SandboxForceSensor": "._sensor",
    "approach_movement": "._scenarios",
    "SandboxTaxelSensor": "._taxels",
    "TaxelModel": "._taxels",
    "fit_taxel_model": "._taxels",
    "force_components": "._taxels",
    "raking_labels": "._taxels",
    "record_movements": "._scenarios",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
