"""hapticframe: find objects buried in granular media by touch.

The core defines seven plugin kinds (:mod:`hapticframe.kinds`), discovers plugins through
the ``hapticframe`` entry-point group, validates experiment files, assembles the configured
components and runs them. Everything scientific lives in plugins.
"""

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
    UsageError,
)
from ._kind import Kind
from ._manager import get_plugin_manager, get_registry, make_plugin_manager
from ._registry import BrokenPlugin, Registered, Registry, Source
from ._session import RunSummary, run_experiment
from ._scene import Circle, Ellipse, Material, Polygon, RegionConfig, Scene
from ._specs import (
    BenchSpec,
    ClassifierSpec,
    FeatureExtractorSpec,
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

__all__ = [
    "BenchOptions",
    "BenchSpec",
    "BrokenPlugin",
    "Circle",
    "ClassifierSpec",
    "Ellipse",
    "Experiment",
    "ExperimentError",
    "FeatureExtractorSpec",
    "HapticframeError",
    "Issue",
    "Kind",
    "MapSpec",
    "Material",
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
    "RunSettings",
    "RunSummary",
    "Scene",
    "SensorModelSpec",
    "SensorSpec",
    "Source",
    "UsageError",
    "__version__",
    "get_plugin_manager",
    "get_registry",
    "hookimpl",
    "make_plugin_manager",
    "run_experiment",
    "validate_file",
    "validate_mapping",
]
