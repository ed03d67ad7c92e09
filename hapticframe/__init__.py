"""hapticframe: find objects buried in granular media by touch.

The core defines seven plugin kinds (:mod:`hapticframe.kinds`), discovers plugins through
the ``hapticframe`` entry-point group, validates experiment files, assembles the configured
components and runs them. Everything scientific lives in plugins.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from hapticframe._lazy import lazy_exports as lazy_exports

# The library logs through `logging` and configures no output: the application (the
# `hapticframe` command, a notebook, a lab's script) decides what is shown.
logging.getLogger(__name__).addHandler(logging.NullHandler())

# Public names resolve on first use (PEP 562), so that `hapticframe --help` and the light
# commands pay only for what they touch.
_LAZY = {
    "BenchOptions": "hapticframe.cli._bench",
    "BenchSpec": "hapticframe._specs",
    "BrokenPlugin": "hapticframe._registry",
    "CALIBRATION_CLASSES": "hapticframe.calibration",
    "read_calibration_run": "hapticframe.calibration",
    "Circle": "hapticframe._scene",
    "ClassifierSpec": "hapticframe._specs",
    "Ellipse": "hapticframe._scene",
    "ComponentView": "hapticframe._config",
    "DirectoryBusy": "hapticframe._lock",
    "Experiment": "hapticframe._config",
    "ExperimentError": "hapticframe._errors",
    "Finding": "hapticframe._config",
    "Size": "hapticframe._config",
    "OutputError": "hapticframe._atomic",
    "apply_overrides": "hapticframe._config._overrides",
    "validate_with_overrides": "hapticframe._config._overrides",
    "atomic_path": "hapticframe._atomic",
    "channel_disagreement": "hapticframe._contracts",
    "atomic_write": "hapticframe._atomic",
    "save_npz": "hapticframe._atomic",
    "ValidationContext": "hapticframe._config",
    "FeatureExtractorSpec": "hapticframe._specs",
    "HapticframeError": "hapticframe._errors",
    "Issue": "hapticframe._errors",
    "ChannelSpec": "hapticframe._contracts",
    "Kind": "hapticframe._kind",
    "Knob": "hapticframe._specs",
    "MapSpec": "hapticframe._specs",
    "Material": "hapticframe._scene",
    "PlannerSpec": "hapticframe._specs",
    "PluginConfig": "hapticframe._specs",
    "PluginConflictError": "hapticframe._errors",
    "PluginError": "hapticframe._errors",
    "PluginImportError": "hapticframe._errors",
    "PluginSpec": "hapticframe._specs",
    "Polygon": "hapticframe._scene",
    "RegionConfig": "hapticframe._scene",
    "Registered": "hapticframe._registry",
    "Registry": "hapticframe._registry",
    "RobotSpec": "hapticframe._specs",
    "RunError": "hapticframe._errors",
    "RunSettings": "hapticframe._config",
    "RunInconclusive": "hapticframe.run._verdict",
    "RunInterrupted": "hapticframe._errors",
    "RunSummary": "hapticframe.run._results",
    "Scene": "hapticframe._scene",
    "SensorModelSpec": "hapticframe._specs",
    "SensorSpec": "hapticframe._specs",
    "SessionView": "hapticframe._session_view",
    "Source": "hapticframe._registry",
    "UsageError": "hapticframe._errors",
    "__version__": "hapticframe._version",
    "lazy_exports": "hapticframe._lazy",
    "get_plugin_manager": "hapticframe._manager",
    "get_registry": "hapticframe._manager",
    "hookimpl": ".hookspecs",
    "lock_directory": "hapticframe._lock",
    "make_plugin_manager": "hapticframe._manager",
    "run_experiment": "hapticframe.record._recorded",
    "validate_file": "hapticframe._config",
    "validate_mapping": "hapticframe._config",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_exports(__name__, _LAZY)


if TYPE_CHECKING:  # static type checkers see the real imports (each an explicit re-export)
    from hapticframe._config import Experiment as Experiment
    from hapticframe._config import RunSettings as RunSettings
    from hapticframe._config import validate_file as validate_file
    from hapticframe._config import validate_mapping as validate_mapping
    from hapticframe._errors import ExperimentError as ExperimentError
    from hapticframe._errors import HapticframeError as HapticframeError
    from hapticframe._errors import Issue as Issue
    from hapticframe._errors import PluginConflictError as PluginConflictError
    from hapticframe._errors import PluginError as PluginError
    from hapticframe._errors import PluginImportError as PluginImportError
    from hapticframe._errors import RunError as RunError
    from hapticframe._errors import RunInterrupted as RunInterrupted
    from hapticframe._errors import UsageError as UsageError
    from hapticframe._kind import Kind as Kind
    from hapticframe._lock import DirectoryBusy as DirectoryBusy
    from hapticframe._lock import lock_directory as lock_directory
    from hapticframe._manager import get_plugin_manager as get_plugin_manager
    from hapticframe._manager import get_registry as get_registry
    from hapticframe._manager import make_plugin_manager as make_plugin_manager
    from hapticframe._registry import BrokenPlugin as BrokenPlugin
    from hapticframe._registry import Registered as Registered
    from hapticframe._registry import Registry as Registry
    from hapticframe._registry import Source as Source
    from hapticframe._scene import Circle as Circle
    from hapticframe._scene import Ellipse as Ellipse
    from hapticframe._scene import Material as Material
    from hapticframe._scene import Polygon as Polygon
    from hapticframe._scene import RegionConfig as RegionConfig
    from hapticframe._scene import Scene as Scene
    from hapticframe._session_view import SessionView as SessionView
    from hapticframe._specs import BenchSpec as BenchSpec
    from hapticframe._specs import ClassifierSpec as ClassifierSpec
    from hapticframe._specs import FeatureExtractorSpec as FeatureExtractorSpec
    from hapticframe._specs import Knob as Knob
    from hapticframe._specs import MapSpec as MapSpec
    from hapticframe._specs import PlannerSpec as PlannerSpec
    from hapticframe._specs import PluginConfig as PluginConfig
    from hapticframe._specs import PluginSpec as PluginSpec
    from hapticframe._specs import RobotSpec as RobotSpec
    from hapticframe._specs import SensorModelSpec as SensorModelSpec
    from hapticframe._specs import SensorSpec as SensorSpec
    from hapticframe._version import __version__ as __version__
    from hapticframe.calibration import CALIBRATION_CLASSES as CALIBRATION_CLASSES
    from hapticframe.calibration import read_calibration_run as read_calibration_run
    from hapticframe.cli._bench import BenchOptions as BenchOptions
    from hapticframe.hookspecs import hookimpl as hookimpl
    from hapticframe.record._recorded import run_experiment as run_experiment
    from hapticframe.run._results import RunSummary as RunSummary
    from hapticframe.run._verdict import RunInconclusive as RunInconclusive
