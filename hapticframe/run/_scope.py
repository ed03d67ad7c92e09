"""One run scope for ``run``, ``replay`` and ``train``: an output directory's whole life.

A command that writes results supplies only what it builds and what it drives;
:func:`run_scope` owns the rest, in this order:

1. the output directory (:class:`~hapticframe.run._results.OutputDir`): checked, locked for
   this process, cleared with ``--overwrite``, its record saying ``running`` before
   anything is built;
2. SIGTERM turned into :class:`~hapticframe.RunInterrupted` (main thread only);
3. the exit stack the components are built on (:meth:`RunScope.build`), which closes them
   in reverse order, a ``close()`` that raises collected, never hiding the outcome;
4. the session (:meth:`RunScope.start_session`) and its recording, opened through the
   :class:`RecordingOpener` the caller hands in: the run layer never imports the writer
   (``run.mcap``'s lives in :mod:`hapticframe.record`), it only knows
   :class:`RecordingWriter`;
5. the outcome: a device failure or an interrupt halts every robot before anything is
   released; every failure becomes the record's ``status`` and ``error``;
6. the end: the recording closed, the staged files moved in (or, for a command that keeps
   nothing of a failure, dropped), the final record written, the lock released. A command
   that failed before anything was built leaves nothing behind.
"""

from __future__ import annotations

import json
import logging
import signal
import threading
import time
import types
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING, Any

from hapticframe._atomic import OutputError
from hapticframe._errors import HapticframeError, RunError, RunInterrupted
from hapticframe.devices import DeviceError
from hapticframe.run._channels import METRICS, RecordingOpener, RecordingWriter
from hapticframe.run._components import Components
from hapticframe.run._loop import devices_of
from hapticframe.run._results import OutputDir, run_record, save_outputs
from hapticframe.run._safety import stop_robots
from hapticframe.run._session import Session

if TYPE_CHECKING:
    from hapticframe._config import Experiment
    from hapticframe.kinds import Component

__all__ = ["RecordingOpener", "RecordingWriter", "RunScope", "run_scope"]

_log = logging.getLogger("hapticframe.run")

#: Receives ``(component id, exception)`` for each ``close()`` that raised.
CloseErrorHandler = Callable[[str, BaseException], None]


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into :class:`RunInterrupted` while the command runs (main thread only),
    so that components are closed and the record is written as for Ctrl-C."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: types.FrameType | None) -> None:
        raise RunInterrupted("SIGTERM")

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def _signals_held() -> Iterator[None]:
    """Ignore SIGINT and SIGTERM while the robots are being stopped (main thread only): a
    second Ctrl-C must not cut the halting of the robots short."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def blame(exc: BaseException, components: Mapping[str, Component]) -> str:
    """`` in 'id' (kind 'type')`` for the innermost component the traceback passes through."""
    ids = {id(c): cid for cid, c in components.items()}
    found = ""
    tb = exc.__traceback__
    while tb is not None:
        owner = tb.tb_frame.f_locals.get("self")
        if owner is not None and id(owner) in ids:
            component = components[ids[id(owner)]]
            found = f" in {ids[id(owner)]!r} ({component.kind})"
        tb = tb.tb_next
    return found


def device_health(components: Mapping[str, Component]) -> dict[str, dict[str, int]]:
    """Each device's health counters, by component id."""
    return {cid: dict(d.health.as_dict()) for cid, d in devices_of(components).items()}


def recording_metadata(experiment: Experiment, started_utc: str) -> dict[str, str]:
    """The recording's ``hapticframe`` metadata: what report, view and replay read."""
    return {
        "name": experiment.model.name, "seed": str(experiment.seed),
        "experiment_file": str(experiment.file), "started_utc": started_utc,
        # The scene, region and settings for report, view and replay.
        "config": json.dumps(experiment.resolved_config()),
    }


@dataclass
class RunScope:
    """What :func:`run_scope` hands the command: the directory, the exit stack, the session.

    The command builds through :meth:`build`, starts its session with
    :meth:`start_session` (a run or a replay) and says it succeeded with :meth:`save`
    (a session's ``trace.npz`` and ``metrics.json``) or :meth:`succeed`.
    """

    directory: OutputDir
    head: Mapping[str, Any]
    #: What the command is called in messages ("run", "replay", "training run").
    what: str
    started_utc: str
    stack: ExitStack = field(default_factory=ExitStack)
    components: Components | None = None
    session: Session | None = None
    #: Builds the final record from the scope (default: the session's ``run.json``).
    final_record: Callable[[RunScope], dict[str, Any]] | None = None
    status: str = "running"
    error: str | None = None
    signal_name: str | None = None
    close_errors: list[str] = field(default_factory=list)
    #: The files moved into the directory when the command ended.
    files: list[str] = field(default_factory=list)
    started: float = field(default_factory=time.perf_counter)

    @property
    def out(self) -> Path:
        """The ``--out`` directory."""
        return self.directory.path

    @property
    def staging(self) -> Path:
        """Where the command writes its files until it ends."""
        return self.directory.staging

    def on_close_error(self, component_id: str, exc: BaseException) -> None:
        """The handler of a ``close()`` that raised: the command fails with it."""
        self.close_errors.append(f"closing {component_id!r} failed: {type(exc).__name__}: {exc}")

    def build(self, builder: Callable[[ExitStack, CloseErrorHandler], Components]
              ) -> Components:
        """Build the command's components with ``builder(stack, on_close_error)``; the
        scope's stack closes them when the command ends in any way."""
        self.components = builder(self.stack, self.on_close_error)
        return self.components

    def start_session(self, experiment: Experiment, echo: Callable[[str], None], *,
                      recording: RecordingOpener | None = None) -> Session:
        """The session of a run or replay over the built components; its recording opened
        with ``recording`` when ``run.record`` asks for one; the session hooks told."""
        if self.components is None:
            raise RuntimeError("start_session() before build()")
        session = Session(experiment, self.staging, self.components, echo,
                          results_dir=self.out)
        session.started_utc = self.started_utc
        self.session = session
        if session.settings.record:
            if recording is None:
                session.details["recording"] = "none: the caller gave no recording writer"
            else:
                session.recording = recording(
                    self.staging, recording_metadata(experiment, self.started_utc))
        session.hook.hapticframe_session_start(session=session.view())
        return session

    def save(self, metrics: Mapping[str, Any]) -> None:
        """The session succeeded: ``/metrics`` into the recording (what ``metrics.json``
        says and each component's own part of it), ``trace.npz`` and ``metrics.json``."""
        session = self._session()
        if session.recording is not None:
            session.recording.event(METRICS.name, METRICS.schema, {
                "metrics": dict(metrics), "components": session.component_metrics})
        save_outputs(session, metrics)
        self.succeed()

    def succeed(self) -> None:
        """The command did what it was asked: its status is ``ok``."""
        self._set_status("ok")

    def stop_robots(self, reason: str) -> tuple[list[str], list[str]]:
        """Halt every robot (``reason``) and deactivate those that are devices, before any
        other component is released; the record lists them (``details.halted_robots``)."""
        if self.components is None:
            return [], []
        with _signals_held():
            halted, failures = stop_robots(self.components, reason)
        details = self.session.details if self.session is not None else {}
        if halted or failures:
            details["halted_robots"] = {"reason": reason, "robots": halted}
        if failures:
            details["halt_errors"] = failures
        return halted, failures

    # --- the end -----------------------------------------------------------------------------

    def _session(self) -> Session:
        if self.session is None:
            raise RuntimeError("no session: start_session() first")
        return self.session

    def _set_status(self, status: str, error: str | None = None) -> None:
        self.status, self.error = status, error
        if self.session is not None:
            self.session.status = status

    def _failed(self, exc: BaseException) -> BaseException | None:
        """The outcome of ``exc``; the exception to raise instead of it (None: ``exc``)."""
        if self.components is None:
            return None  # nothing built: nothing to stop, nothing will be recorded
        components = self.components
        if isinstance(exc, DeviceError):
            # Stop every actuator before anything else is released.
            halted, failures = self.stop_robots("device failure")
            error = f"device failure{blame(exc, components)}: {exc}"
            if halted:
                error += f" (halted {', '.join(repr(r) for r in halted)})"
            if failures:
                error += "; " + "; ".join(failures)
            self._set_status("failed", error)
            return RunError(f"the {self.what} failed: {error}")
        if isinstance(exc, RunInterrupted):
            self.stop_robots("interrupted")
            self._set_status("interrupted")
            self.signal_name = exc.signal_name
            return None
        if isinstance(exc, KeyboardInterrupt):
            self.stop_robots("interrupted")
            self._set_status("interrupted")
            self.signal_name = "SIGINT"
            return RunInterrupted("SIGINT")
        if isinstance(exc, HapticframeError):
            self._set_status("failed", str(exc))
            return None
        if isinstance(exc, Exception):
            error = f"{type(exc).__name__}{blame(exc, components)}: {exc}"
            self._set_status("failed", error)
            return RunError(f"the {self.what} failed: {error}")
        self._set_status("failed", type(exc).__name__)
        return None

    def _close_recording(self) -> OutputError | None:
        """Write the devices' last counters and the recording's summary; the error when the
        file cannot be written."""
        recording = self.session.recording if self.session is not None else None
        if recording is None or recording.closed:
            return None
        try:
            try:
                health = device_health(self.components or {})
            except Exception:  # a broken device's counters never stop the recording's close
                health = {}
            try:
                if health:
                    recording.health(health)
            finally:
                recording.close()
        except OutputError as exc:
            return exc
        return None

    def _end(self, primary: BaseException | None, keep_failed: bool) -> OutputError | None:
        """Close the recording, write the final record and move the files in; the
        recording's error, if any."""
        session = self.session
        details = session.details if session is not None else {}
        if session is not None and session.safety_halts:
            details["safety_halts"] = session.safety_halts
        if self.status != "ok" and self.components is not None:
            try:
                health = device_health(self.components)
            except Exception:  # a broken device's counters never hide the command's error
                health = {}
            if health:
                details["devices"] = health
        if self.close_errors and self.status == "ok":
            self._set_status("failed", "; ".join(self.close_errors))
        elif self.close_errors:
            details["close_errors"] = self.close_errors
        recording_error = self._close_recording()
        if recording_error is not None:
            if self.status == "ok":
                self._set_status("failed", str(recording_error))
            else:  # the command is already failing: its first error stays the error
                details["recording_error"] = str(recording_error)
        record = self._record()
        directory = self.directory
        try:
            if self.status == "ok" or keep_failed:
                files = directory.commit(record)
            else:  # half-written results must never be loaded: keep none
                directory.drop_staging()
                files = []
            directory.finish(record, files)
            self.files = sorted(files)
        except OutputError as exc:
            if primary is None:
                raise OutputError(f"{exc}; {directory.record_path} still says the "
                                  f"{self.what} is unfinished", exc.path) from exc
            _log.error("%s; %s still says the %s is unfinished", exc, directory.record_path,
                       self.what)
        return recording_error

    def _record(self) -> dict[str, Any]:
        if self.final_record is not None:
            return self.final_record(self)
        if self.session is not None:
            wall = time.perf_counter() - self.session.started
            return run_record(self.session, wall, self.error, self.signal_name)
        record = {**self.head, "status": self.status, "error": self.error,
                  "wall_time_s": time.perf_counter() - self.started}
        if self.signal_name is not None:
            record["signal"] = self.signal_name
        return record


@contextmanager
def run_scope(
    out_dir: str | Path,
    head: Mapping[str, Any],
    *,
    what: str = "run",
    record: str = "run.json",
    overwrite: bool = False,
    min_free_bytes: int | None = None,
    inputs: Sequence[str | Path] = (),
    keep_failed: bool = True,
    started_utc: str | None = None,
) -> Iterator[RunScope]:
    """The life of one command's output directory (see the module's notes).

    ``head`` is what the record says while the command runs (``status: running`` is
    added); ``record`` its file name (``run.json``, ``train.json``); ``inputs`` the files
    the command reads (an output directory that is also an input is refused);
    ``keep_failed=False`` keeps none of a failed command's files.

    Raises
    ------
    UsageError, OutputError
        From :meth:`~hapticframe.run._results.OutputDir.prepare`, before anything runs.
    RunError
        The command failed (a device failure, a bug in a component: the message names
        it), or a component's ``close()`` raised.
    RunInterrupted
        On Ctrl-C (SIGINT) or SIGTERM.
    OutputError
        The recording or a result file cannot be written.
    """
    directory = OutputDir.prepare(out_dir, record=record, command=what, overwrite=overwrite,
                                  min_free=min_free_bytes, inputs=inputs)
    try:
        scope = RunScope(directory, dict(head), what, started_utc or datetime.now(
            timezone.utc).isoformat(timespec="seconds"))
        # Before anything is built: a command killed from here on leaves a record saying so.
        directory.begin(head)
        primary: BaseException | None = None
        recording_error: OutputError | None = None
        try:
            with _sigterm_as_interrupt(), scope.stack:
                try:
                    yield scope
                except BaseException as exc:
                    instead = scope._failed(exc)
                    if instead is not None:
                        raise instead from exc
                    raise
                finally:
                    if scope.session is not None:
                        scope.session.hook.hapticframe_session_finish(
                            session=scope.session.view(), status=scope.status)
            # The stack has closed every component by now.
        except BaseException as exc:
            primary = exc
            raise
        finally:
            if scope.components is None:
                directory.discard()  # it failed to build: nothing was written
            else:
                recording_error = scope._end(primary, keep_failed)
        if recording_error is not None:
            raise recording_error
        if scope.close_errors:
            raise RunError("; ".join(scope.close_errors))
    finally:
        directory.release()

