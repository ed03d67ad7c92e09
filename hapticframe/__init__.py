"""hapticframe: find objects buried in granular media by touch.

The core defines seven plugin kinds (:mod:`hapticframe.kinds`), discovers plugins through
the ``hapticframe`` entry-point group, validates experiment files, assembles the configured
components and runs them. Everything scientific lives in plugins.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

# The library logs through `logging` and configures no output: the application (the
# `hapticframe` command, a notebook, a lab's script) decides what is shown.
logging.getLogger(__name__).addHandler(logging.NullHandler())

# Public names resolve on first use (PEP 562), so that `hapticframe --help` and the light
# commands pay only for what they touch.
_LAZY = {
    "BenchOptions": "hapticframe.cli._bench",
    "BenchSpec": "hapticframe._specs",
    "BrokenPlugin": "hapticframe._registry",
    "Circle": "hapticframe._scene",
    "ClassifierSpec": "hapticframe._specs",
    "Ellipse": "hapticframe._scene",
    "ComponentView": "hapticframe._config",
    "Experiment": "hapticframe._config",
    "ExperimentError": "hapticframe._errors",
    "Finding": "hapticframe._config",
    "OutputError": "hapticframe._atomic",
    "apply_overrides": "hapticframe._config._overrides",
    "validate_with_overrides": "hapticframe._config._overrides",
    "atomic_path": "hapticframe._atomic",
    "atomic_write": "hapticframe._atomic",
    "save_npz": "hapticframe._atomic",
    "ValidationContext": "hapticframe._config",
    "FeatureExtractorSpec": "hapticframe._specs",
    "HapticframeError": "hapticframe._errors",
    "Issue": "hapticframe._errors",
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
    "RunInterrupted": "hapticframe._errors",
    "RunSummary": "hapticframe.run._results",
    "Scene": "hapticframe._scene",
    "SensorModelSpec": "hapticframe._specs",
    "SensorSpec": "hapticframe._specs",
    "SessionView": "hapticframe._session_view",
    "Source": "hapticframe._registry",
    "UsageError": "hapticframe._errors",
    "__version__": "hapticframe._version",
    "get_plugin_manager": "hapticframe._manager",
    "get_registry": "hapticframe._manager",
    "hookimpl": ".hookspecs",
    "make_plugin_manager": "hapticframe._manager",
    "run_experiment": "hapticframe.run._run",
    "validate_file": "hapticframe._config",
    "validate_mapping": "hapticframe._config",
}

__all__ = [
    "BenchOptions",
    "BenchSpec",
    "BrokenPlugin",
    "Circle",
    "ClassifierSpec",
    "ComponentView",
    "Ellipse",
    "Experiment",
    "ExperimentError",
    "FeatureExtractorSpec",
    "Finding",
    "HapticframeError",
    "Issue",
    "Kind",
    "Knob",
    "MapSpec",
    "Material",
    "OutputError",
    "PlannerSpec",
    "PluginConfig",
    "PluginConflictError",
    "PluginError",
    "PluginImportError",
    "PluginSpec",
    "Polygon",
    "RegionConfig",
    "Registered",
    "Registry",
    "RobotSpec",
    "RunError",
    "RunInterrupted",
    "RunSettings",
    "RunSummary",
    "Scene",
    "SensorModelSpec",
    "SensorSpec",
    "SessionView",
    "Source",
    "UsageError",
    "ValidationContext",
    "__version__",
    "apply_overrides",
    "atomic_path",
    "atomic_write",
    "get_plugin_manager",
    "get_registry",
    "hookimpl",
    "make_plugin_manager",
    "run_experiment",
    "save_npz",
    "validate_file",
    "validate_mapping",
    "validate_with_overrides",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'hapticframe' has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:  # static type checkers see the real imports
    from hapticframe._config import Experiment, RunSettings, validate_file, validate_mapping
    from hapticframe._errors import (
        ExperimentError,
        HapticframeError,
        Issue,
        PluginConflictError,
        PluginError,
        PluginImportError,
        RunError,
        RunInterrupted,
        UsageError,
    )
    from hapticframe._kind import Kind
    from hapticframe._manager import get_plugin_manager, get_registry, make_plugin_manager
    from hapticframe._registry import BrokenPlugin, Registered, Registry, Source
    from hapticframe._scene import Circle, Ellipse, Material, Polygon, RegionConfig, Scene
    from hapticframe._session_view import SessionView
    from hapticframe._specs import (
        BenchSpec,
        ClassifierSpec,
        FeatureExtractorSpec,
        Knob,
        MapSpec,
        PlannerSpec,
        PluginConfig,
        PluginSpec,
        RobotSpec,
        SensorModelSpec,
        SensorSpec,
    )
    from hapticframe._version import __version__
    from hapticframe.cli._bench import BenchOptions
    from hapticframe.hookspecs import hookimpl
    from hapticframe.run._results import RunSummary
    from hapticframe.run._run import run_experiment
