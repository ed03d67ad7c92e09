"""The read-only face of a run that hooks receive (``hapticframe_session_start`` and kin).

Declared in the kernel so that the hook specifications can name it; the run package
implements it over its private session state.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from hapticframe._config._model import Experiment, RunSettings
    from hapticframe.kinds import Component, MovementResult

__all__ = ["SessionView"]


class SessionView(ABC):
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

    __slots__ = ()

    @property
    @abstractmethod
    def experiment(self) -> Experiment: ...

    @property
    @abstractmethod
    def name(self) -> str: ...

    @property
    @abstractmethod
    def seed(self) -> int: ...

    @property
    @abstractmethod
    def out_dir(self) -> Path: ...

    @property
    @abstractmethod
    def write_dir(self) -> Path: ...

    @property
    @abstractmethod
    def settings(self) -> RunSettings: ...

    @property
    @abstractmethod
    def components(self) -> Mapping[str, Component]: ...

    @property
    @abstractmethod
    def movements(self) -> tuple[MovementResult, ...]: ...

    @property
    @abstractmethod
    def details(self) -> Mapping[str, Any]: ...

    @property
    @abstractmethod
    def status(self) -> str: ...

    def __repr__(self) -> str:
        return f"<SessionView {self.name!r} status={self.status!r} out_dir={str(self.out_dir)!r}>"
