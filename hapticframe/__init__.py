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
    "BenchOptions": "._bench",
    "BenchSpec": "._specs",
    "BrokenPlugin": "._registry",
    "Circle": "._scene",
    "ClassifierSpec": "._specs",
    "Ellipse": "._scene",
    "ComponentView": "._config",
    "Experiment": "._config",
    "ExperimentError": "._errors",
    "Finding": "._config",
    "Size": "._config",
    "OutputError": "._results",
    "apply_overrides": "._overrides",
    "validate_with_overrides": "._overrides",
    "atomic_path": "._results",
    "atomic_write": "._results",
    "save_npz": "._results",
    "ValidationContext": "._config",
    "FeatureExtractorSpec": "._specs",
    "HapticframeError": "._errors",
    "Issue": "._errors",
    "Kind": "._kind",
    "Knob": "._specs",
    "MapSpec": "._specs",
    "Material": "._scene",
    "PlannerSpec": "._specs",
    "PluginConfig": "._specs",
    "PluginConflictError": "._errors",
    "PluginError": "._errors",
    "PluginImportError": "._errors",
    "PluginSpec": "._specs",
    "Polygon": "._scene",
    "RegionConfig": "._scene",
    "Registered": "._registry",
    "Registry": "._registry",
    "RobotSpec": "._specs",
    "RunError": "._errors",
    "RunSettings": "._config",
    "RunInterrupted": "._errors",
    "RunSummary": "._results",
    "Scene": "._scene",
    "SensorModelSpec": "._specs",
    "SensorSpec": "._specs",
    "SessionView": "._session",
    "Source": "._registry",
    "UsageError": "._errors",
    "__version__": "._version",
    "get_plugin_manager": "._manager",
    "get_registry": "._manager",
    "hookimpl": ".hookspecs",
    "make_plugin_manager": "._manager",
    "run_experiment": "._run",
    "validate_file": "._config",
    "validate_mapping": "._config",
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
    "Size",
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
    from ._bench import BenchOptions
    from ._config import Experiment, RunSettings, validate_file, validate_mapping
    from ._errors import (
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
    from ._kind import Kind
    from ._manager import get_plugin_manager, get_registry, make_plugin_manager
    from ._registry import BrokenPlugin, Registered, Registry, Source
    from ._results import RunSummary
    from ._run import run_experiment
    from ._scene import Circle, Ellipse, Material, Polygon, RegionConfig, Scene
    from ._session import SessionView
    from ._specs import (
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
    from ._version import __version__
    from .hookspecs import hookimpl
