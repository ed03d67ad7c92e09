"""Build an experiment's components, inputs first, and close them again.

Every component is built under a :class:`contextlib.ExitStack` that the caller owns: a
failure while building closes what was already built, and leaving the stack closes every
component in reverse build order, each ``close()`` guarded, so one that raises neither
leaves the others open nor hides the run's own outcome.

Once everything is built, every :class:`~hapticframe.kinds.Device` is configured and
activated, in build order (a sensor after the robot it is mounted on). Leaving the stack
deactivates and cleans up the devices in reverse order before any component is closed.
"""

from __future__ import annotations

import logging
import math
import zlib
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from typing import Any

import numpy as np

from hapticframe._config import ComponentEntry, Experiment, contract_mismatch
from hapticframe._contracts import ChannelSpec
from hapticframe._errors import ExperimentError, HapticframeError, Issue, RunError
from hapticframe._kind import Kind
from hapticframe.kinds import (
    BuildContext,
    ChannelInfo,
    Component,
    Device,
    FeatureExtractor,
    Robot,
    RunClock,
    Sensor,
)
from hapticframe.run._components import Components

__all__ = ["LEAVE_OUT", "Substitute", "activate_devices", "build_components", "component_rng"]

_log = logging.getLogger(__name__)

#: Receives ``(component id, exception)`` for each ``close()`` that raised.
CloseErrorHandler = Callable[[str, BaseException], None]


@dataclass(frozen=True)
class Substitute:
    """What to build in place of a configured component (a replay's recorded sensor)."""

    factory: Callable[[Any, BuildContext], Any]
    config: Any
    plugin: str


#: ``choose(entry)`` returns this for a component the command does not build.
LEAVE_OUT = "leave out"
#: What a command builds of each entry: as configured (None), :data:`LEAVE_OUT`, or a
#: :class:`Substitute`.
Chooser = Callable[[ComponentEntry], "Substitute | str | None"]


def component_rng(seed: int, component_id: str) -> np.random.Generator:
    """The generator of one component: independent streams per id, fixed by the seed."""
    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(zlib.crc32(component_id.encode("utf-8")),))
    )


def _log_close_error(component_id: str, exc: BaseException) -> None:
    _log.warning("closing %r failed: %s: %s", component_id, type(exc).__name__, exc)


def _closer(component: Component, on_error: CloseErrorHandler) -> Callable[[], None]:
    def close() -> None:
        try:
            component.close()
        except Exception as exc:  # one failing close must not keep the others open
            on_error(component.id, exc)

    return close


def build_components(
    experiment: Experiment,
    stack: ExitStack,
    *,
    progress: bool = True,
    on_close_error: CloseErrorHandler = _log_close_error,
    activate: bool = True,
    choose: Chooser | None = None,
    purpose: str = "",
) -> Components:
    """Import and construct every component, inputs first; ``stack`` closes them.

    ``choose(entry)`` (a replay's) may leave a component out (:data:`LEAVE_OUT`) or build
    another in its place (:class:`Substitute`); ``purpose`` ends the messages of a build
    that fails (``" for the replay"``).

    Each built component's ``close()`` is pushed onto ``stack`` as soon as it is built;
    a ``close()`` that raises is passed to ``on_close_error`` (default: logged) and the
    others are still closed. ``progress`` is handed to each component
    (:attr:`BuildContext.progress`). With ``activate`` (the default) every device is then
    configured and activated (:func:`activate_devices`).

    Raises
    ------
    ExperimentError
        When a plugin rejects its configuration while being built (a ``ValueError`` or
        ``KeyError``; exit status 2).
    RunError
        When building fails otherwise (a device's ``OSError``, a ``TypeError`` in the
        plugin, a component of the wrong kind), or a device fails to come up, naming the
        component (exit status 1).
    PluginImportError
        When an implementation cannot be imported.
    """
    scene = experiment.model.scene
    # One clock for the run, handed to every component: its period is the first robot's
    # control period (from its config, before anything is built), else the open loop's tick.
    clock = RunClock(_control_period_s(experiment))
    built = Components(clock)
    for entry in experiment.components:
        chosen = choose(entry) if choose is not None else None
        if chosen == LEAVE_OUT:
            continue
        if isinstance(chosen, Substitute):
            factory, config, plugin = chosen.factory, chosen.config, chosen.plugin
        else:
            factory, config, plugin = entry.registered.spec.load_factory(), entry.config, entry.type
        context = BuildContext(
            id=entry.id,
            rng=component_rng(experiment.seed, entry.id),
            # Inputs left out (a replay's robots) are not handed in.
            inputs={name: built[name] for name in entry.inputs if name in built},
            scene=scene,
            progress=progress,
            clock=clock,
        )
        try:
            component = factory(config, context)
        except (ValueError, KeyError) as exc:
            raise ExperimentError(experiment.file, [Issue(
                entry.path, f"cannot build {_named(entry)}{purpose}: {exc}",
            )]) from exc
        except HapticframeError:
            raise
        except Exception as exc:
            raise RunError(f"cannot build {_named(entry)}{purpose}: "
                           f"{type(exc).__name__}: {exc}") from exc
        if isinstance(component, Component):
            stack.callback(_closer(component, on_close_error))
        built.add(entry.id, entry.kind, component, plugin=plugin)
    _check_built_channels(experiment, built)
    if built.robots:
        # The robots' time: the latest state of any (in a team, the one that moves now).
        robots = tuple(built.robots.values())
        clock.follow(lambda: _latest_time_s(robots), 1.0 / float(robots[0].control_rate_hz))
    if activate:
        names = {e.id: _named(e) for e in experiment.components}
        activate_devices(built, stack, on_close_error, names)
    return built


def _releaser(
    component_id: str, device: Device, on_error: CloseErrorHandler
) -> Callable[[], None]:
    def release() -> None:
        for step in (device.deactivate, device.cleanup):
            try:
                step()
            except Exception as exc:  # one failing device must not keep the others active
                on_error(component_id, exc)

    return release


def activate_devices(
    components: Components,
    stack: ExitStack,
    on_error: CloseErrorHandler = _log_close_error,
    names: dict[str, str] | None = None,
) -> list[str]:
    """Configure and activate every :class:`~hapticframe.kinds.Device` in build order; the
    ids activated. ``stack`` deactivates and cleans each up (in reverse order), also when a
    later one fails to come up.

    Raises
    ------
    RunError
        When a device fails to configure or activate, naming it (exit status 1).
    """
    activated = []
    for cid, component in components.items():
        if not isinstance(component, Device):
            continue
        # Pushed first: a device that fails half way through activation is still released.
        stack.callback(_releaser(cid, component, on_error))
        what = (names or {}).get(cid, repr(cid))
        for step, doing in ((component.configure, "configure"), (component.activate, "activate")):
            try:
                step()
            except HapticframeError:
                raise
            except Exception as exc:
                raise RunError(f"cannot {doing} {what}: {type(exc).__name__}: {exc}") from exc
        activated.append(cid)
    return activated


def _check_built_channels(experiment: Experiment, built: Components) -> None:
    """Each consumer's declared channels against what its built inputs report
    (``Sensor.channels``, ``FeatureExtractor.output_channels``): a producer whose spec
    declares nothing (its channels come from a file, a lab plugin written before
    contracts) is held to the contract here, before the run starts (exit 2, located)."""
    issues = []
    types = {e.id: e.type for e in experiment.components}
    for entry in experiment.components:
        if entry.id not in built or not entry.registered.spec.consumes:
            continue
        for input_id in entry.inputs:
            if input_id not in built:
                continue
            source = built[input_id]
            declared = getattr(source, "channels", None) if isinstance(source, Sensor) else (
                getattr(source, "output_channels", None)
                if isinstance(source, FeatureExtractor) else None
            )
            if not isinstance(declared, Mapping):
                continue
            produced = {
                name: ChannelSpec(tuple(info.shape), str(info.unit))
                for name, info in declared.items() if isinstance(info, ChannelInfo)
            }
            for message in contract_mismatch(
                entry, input_id, types.get(input_id, "?"), produced,
                what_input="delivers (as built)",
            ):
                issues.append(Issue(f"{entry.path}.inputs", message))
    if issues:
        raise ExperimentError(experiment.file, issues)


def _latest_time_s(robots: tuple[Robot, ...]) -> float:
    """The time of the robots' latest state (NaN before any has one: the clock holds)."""
    times = [float(r.state.timestamp_s) for r in robots if r.state is not None]
    return max(times) if times else math.nan


def _control_period_s(experiment: Experiment) -> float:
    """The run's control period: the first robot's ``control_rate_hz`` where its config
    says it, else ``run.live_tick_s`` (an open loop advances its clock by it per read)."""
    for entry in experiment.components:
        if entry.kind is Kind.ROBOT:
            rate = getattr(entry.config, "control_rate_hz", None)
            if isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0:
                return 1.0 / float(rate)
            break
    return float(experiment.model.run.live_tick_s)


def _named(entry: ComponentEntry) -> str:
    return f"{entry.id!r} ({entry.kind} {entry.type!r})"
