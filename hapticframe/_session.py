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

from ._components import Components
from ._config import Experiment, RunSettings
from ._streams import TraceRecorder
from .kinds import Component, MovementResult

__all__ = ["Session", "SessionView"]


@dataclass
class Session:
    """Everything one run holds while it runs (private to the core's run modules)."""

    experiment: Experiment
    #: The staging folder the run writes into (see :class:`~hapticframe._results.OutputDir`).
    out_dir: Path
    components: Components
    echo: Callable[[str], None]
    #: The ``--out`` directory the staged files move into when the run ends.
    results_dir: Path | None = None
    movements: list[MovementResult] = field(default_factory=list)
    recorder: TraceRecorder = field(default_factory=TraceRecorder)
    #: The run's ``run.mcap`` writer (:class:`~hapticframe._recording.RunRecording`), or
    #: None when ``run.record`` is off.
    recording: Any = None
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
        return SessionView(self)


class SessionView:
    """A run as hooks see it: read-only, and stable across versions of the core.

    Attributes
    ----------
    experiment : Experiment
        The validated experiment (``experiment.model.name``, ``experiment.seed``, ...).
    name : str
    seed : int
    out_dir : Path
        The run's ``--out`` directory, where its results are once it has ended.
    write_dir : Path
        Where the run writes its files while it runs: a staging folder inside ``out_dir``
        whose files move into ``out_dir`` when the run ends and which ``run.json`` then
        lists (a killed run never leaves half its files looking finished). A hook that
        writes files writes them here, with :func:`hapticframe.plotting.save_figure` or
        another atomic writer; a file written straight into ``out_dir`` is not the run's
        (``--overwrite`` will not delete it).
    settings : RunSettings
        The experiment's ``run`` section.
    components : mapping of str to Component
        Every built component by id (read-only mapping).
    movements : tuple of MovementResult
        The exploratory movements so far.
    details : mapping
        What ``run.json`` records under ``details`` so far (read-only).
    status : str
        ``"running"``; in ``hapticframe_session_finish``: ``"ok"``, ``"failed"`` or
        ``"interrupted"``.
    """

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

    def __repr__(self) -> str:
        return f"<SessionView {self.name!r} status={self.status!r} out_dir={str(self.out_dir)!r}>"
