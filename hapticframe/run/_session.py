"""The state of one run, and the read-only view of it that hooks receive.

:class:`Session` is what the run's modules share while an experiment runs (its components,
movements, trace and details); it is private and changes as the run goes. Hooks
(``hapticframe_session_start``, ``hapticframe_session_finish``, ``hapticframe_run_metadata``)
receive a :class:`SessionView`, the public, read-only face of it.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from hapticframe._config import Experiment, RunSettings
from hapticframe._session_view import SessionView
from hapticframe.kinds import Component, MovementResult
from hapticframe.run._channels import RecordingWriter
from hapticframe.run._components import Components
from hapticframe.run._streams import TraceRecorder

__all__ = ["Session"]


@dataclass
class Session:
    """Everything one run holds while it runs (private to the core's run modules)."""

    experiment: Experiment
    #: The staging folder the run writes into (see :class:`~hapticframe.run._results.OutputDir`).
    out_dir: Path
    components: Components
    echo: Callable[[str], None]
    #: The ``--out`` directory the staged files move into when the run ends.
    results_dir: Path | None = None
    movements: list[MovementResult] = field(default_factory=list)
    recorder: TraceRecorder = field(default_factory=TraceRecorder)
    #: The run's recording writer (``run.mcap``'s, handed in by the caller), or None when
    #: ``run.record`` is off or no writer was given.
    recording: RecordingWriter | None = None
    #: Entries for ``run.json``'s ``details`` (training, sensor reads, ...).
    details: dict[str, Any] = field(default_factory=dict)
    started: float = field(default_factory=time.perf_counter)
    started_utc: str | None = None
    status: str = "running"
    #: The largest force magnitude any streamed sensor measured (a channel in ``N``), NaN
    #: when none did: the console's per-movement figure and ``metrics.json`` both use it.
    max_measured_force_n: float = float("nan")
    #: Every halt of the run loop's safety checks (force limit, stalled force stream,
    #: workspace refusal), in order: ``run.json``'s ``details.safety_halts``.
    safety_halts: list[dict[str, Any]] = field(default_factory=list)
    #: Each component's own ``finalize()`` metrics, by id (``run.mcap``'s ``/metrics``).
    component_metrics: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def settings(self) -> RunSettings:
        return self.experiment.model.run

    @property
    def training_sensors(self) -> frozenset[str]:
        """Sensors read only to fit components before the run (``run.train_from``)."""
        return frozenset(self.settings.train_from.values())

    @property
    def hook(self) -> Any:
        return self.experiment.plugin_manager.hook

    def view(self) -> SessionView:
        return _RunSessionView(self)


class _RunSessionView(SessionView):
    """:class:`~hapticframe.SessionView` of a running :class:`Session`."""


    __slots__ = ("_session",)

    def __init__(self, session: Session) -> None:
        self._session = session

    @property
    def experiment(self) -> Experiment:
        return self._session.experiment

    @property
    def name(self) -> str:
        return self._session.experiment.model.name

    @property
    def seed(self) -> int:
        return self._session.experiment.seed

    @property
    def out_dir(self) -> Path:
        return self._session.results_dir or self._session.out_dir

    @property
    def write_dir(self) -> Path:
        return self._session.out_dir

    @property
    def settings(self) -> RunSettings:
        return self._session.settings

    @property
    def components(self) -> Mapping[str, Component]:
        return MappingProxyType(dict(self._session.components))

    @property
    def movements(self) -> tuple[MovementResult, ...]:
        return tuple(self._session.movements)

    @property
    def details(self) -> Mapping[str, Any]:
        return MappingProxyType(dict(self._session.details))

    @property
    def status(self) -> str:
        return self._session.status
