"""Hook specifications: one registration hook per kind plus a few session hooks.

A plugin module implements any of these with :data:`hapticframe.hookimpl` and is listed
under the ``hapticframe`` entry-point group::

    [project.entry-points.hapticframe]
    my-sensor = "my_lab_plugin.plugin"

Registration hooks take no arguments and yield frozen spec records; they must stay
import-light (no torch, no device libraries at module level).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from hapticframe._session_view import SessionView
    from hapticframe._specs import (
        BenchSpec,
        ClassifierSpec,
        FeatureExtractorSpec,
        MapSpec,
        PlannerSpec,
        RobotSpec,
        SensorModelSpec,
        SensorSpec,
    )

__all__ = ["PROJECT_NAME", "hookimpl", "hookspec"]

PROJECT_NAME = "hapticframe"
hookspec = pluggy.HookspecMarker(PROJECT_NAME)
hookimpl = pluggy.HookimplMarker(PROJECT_NAME)


# --- registration: one hook per kind ------------------------------------------------------


@hookspec
def hapticframe_sensors() -> Iterable[SensorSpec]:
    """Yield :class:`~hapticframe.SensorSpec` records for the sensors a plugin provides."""


@hookspec
def hapticframe_feature_extractors() -> Iterable[FeatureExtractorSpec]:
    """Yield :class:`~hapticframe.FeatureExtractorSpec` records."""


@hookspec
def hapticframe_classifiers() -> Iterable[ClassifierSpec]:
    """Yield :class:`~hapticframe.ClassifierSpec` records."""


@hookspec
def hapticframe_sensor_models() -> Iterable[SensorModelSpec]:
    """Yield :class:`~hapticframe.SensorModelSpec` records."""


@hookspec
def hapticframe_maps() -> Iterable[MapSpec]:
    """Yield :class:`~hapticframe.MapSpec` records."""


@hookspec
def hapticframe_planners() -> Iterable[PlannerSpec]:
    """Yield :class:`~hapticframe.PlannerSpec` records."""


@hookspec
def hapticframe_robots() -> Iterable[RobotSpec]:
    """Yield :class:`~hapticframe.RobotSpec` records."""


@hookspec
def hapticframe_benchmarks() -> Iterable[BenchSpec]:
    """Yield :class:`~hapticframe.BenchSpec` records for ``hapticframe bench NAME``."""


# --- session level --------------------------------------------------------------------------


@hookspec(historic=True)
def hapticframe_addhooks(pluginmanager: pluggy.PluginManager) -> None:
    """Add hook specifications of your own (``pluginmanager.add_hookspecs(module)``)."""


@hookspec
def hapticframe_session_start(session: SessionView) -> None:
    """Called after an experiment is built, before its first step.

    ``session`` is a read-only :class:`~hapticframe.SessionView` of the run.
    """


@hookspec
def hapticframe_session_finish(session: SessionView, status: str) -> None:
    """Called once a run ends, before its components are closed; ``status`` is ``"ok"``,
    ``"failed"`` or ``"interrupted"``."""


@hookspec
def hapticframe_run_metadata(session: SessionView) -> Mapping[str, Any] | None:
    """Return extra entries for the run's ``run.json`` (merged under ``"plugins"``)."""


@hookspec
def hapticframe_error_hints(error: BaseException) -> Iterable[str] | None:
    """Return hints to print below an error message (for example, what to install)."""
