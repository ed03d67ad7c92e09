"""``hapticframe run``: one experiment from validated file to written results.

The orchestrator. It calls, in this order and never the other way round:
:mod:`~hapticframe.run._assembly` (build the components under one exit stack),
:mod:`~hapticframe.run._train` (fit before the run, ``run.train_from``),
:mod:`~hapticframe.run._loop` (the closed or open loop), :mod:`~hapticframe.run._evaluate`
(score the run) and :mod:`~hapticframe.run._results` (write ``trace.npz``, ``metrics.json`` and
``run.json``).

``--out`` is checked before anything is built (a directory, writable, enough free space,
no results it may not replace: :class:`~hapticframe.run._results.OutputDir`); ``run.json``
then says ``status: running`` until the run ends, and every file is written atomically
into a staging folder that moves into ``--out`` at the end, so a run killed at any point
leaves a directory that says it is unfinished. An experiment that fails to build writes
nothing.

Devices (:class:`~hapticframe.kinds.Device`) are configured and activated once everything
is built and released, in reverse order, when the run ends in any way. A
:class:`~hapticframe.devices.DeviceError` (a device that cannot recover) first halts every
robot (and deactivates a robot that is a device), then fails the run with a message naming
the device (exit status 1); SIGINT and SIGTERM stop the robots the same way before the run
ends as interrupted (``details.halted_robots`` in ``run.json``). Each device's health
counters go to ``metrics.json`` (``devices``), or to ``run.json`` (``details.devices``)
when the run did not finish.
"""

from __future__ import annotations

import logging
import os
import signal
import threading
import time
import types
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from hapticframe._config import Experiment
from hapticframe._errors import HapticframeError, RunError, RunInterrupted
from hapticframe.devices import DeviceError
from hapticframe.kinds import Component
from hapticframe.run import _assembly
from hapticframe.run._evaluate import score_run
from hapticframe.run._loop import devices_of, run_loop
from hapticframe.run._results import (
    OutputDir,
    OutputError,
    RunSummary,
    environment,
    run_record,
    save_outputs,
)
from hapticframe.run._safety import FORCE_LIMIT, stop_robots
from hapticframe.run._session import Session
from hapticframe.run._train import collect_recordings, fit_components, training_reports

__all__ = ["RunSummary", "run_experiment"]

_log = logging.getLogger("hapticframe.run")


def _fit_before_run(session: Session) -> None:
    """Fit feature extractors and classifiers on the training sensors' recordings."""
    sources = session.settings.train_from
    if not sources:
        return
    started = time.perf_counter()
    recordings = collect_recordings(session.components, sources)
    session.echo(
        f"fitting before the run on {len(recordings)} recordings of "
        f"{', '.join(sorted(set(sources.values())))}"
    )
    trained = fit_components(session.experiment, session.components, recordings,
                             session.settings.label_channel, session.echo)
    session.details["training"] = {
        "recordings": len(recordings),
        "trained": trained,
        "reports": training_reports(session.components, trained),
        "wall_time_s": time.perf_counter() - started,
    }


@contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM into :class:`RunInterrupted` while the run runs (main thread only), so
    that components are closed and ``run.json`` is written as for Ctrl-C."""
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


def _blame(exc: BaseException, components: Mapping[str, Component]) -> str:
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


def _stop_robots(session: Session, reason: str) -> tuple[list[str], list[str]]:
    """Halt every robot (``reason``) and deactivate those that are devices, before any
    other component is released; ``run.json`` records them (``details.halted_robots``)."""
    with _signals_held():
        halted, failures = stop_robots(session.components, reason)
    if halted or failures:
        session.details["halted_robots"] = {"reason": reason, "robots": halted}
    if failures:
        session.details["halt_errors"] = failures
    return halted, failures


def _latency_metric(session: Session) -> int | None:
    """The largest halt latency of the run's force-limit halts (robot steps), or None."""
    latencies = [int(h["latency_samples"]) for h in session.safety_halts
                 if h.get("reason") == FORCE_LIMIT]
    return max(latencies) if latencies else None


def _device_health(components: Mapping[str, Component]) -> dict[str, dict[str, int]]:
    return {cid: dict(d.health.as_dict()) for cid, d in devices_of(components).items()}


def _running_record(experiment: Experiment, started_utc: str) -> dict[str, Any]:
    """What ``run.json`` says while the run runs (its final content replaces it)."""
    return {
        "status": "running",
        "experiment_file": str(experiment.file),
        "name": experiment.model.name,
        "seed": experiment.seed,
        "started_utc": started_utc,
        "pid": os.getpid(),
        "versions": environment(),
    }


def _finish(directory: OutputDir, record: dict[str, Any], primary: BaseException | None) -> None:
    """Move the run's files into place and write the final ``run.json``.

    When that fails (a full disk), ``run.json`` keeps saying ``running`` and the staged
    files stay in the staging folder; the failure is raised, or, when the run is already
    failing, logged beside the first error so that it does not hide it.
    """
    try:
        files = directory.commit(record)
        directory.finish(record, files)
    except OutputError as exc:
        if primary is None:
            raise OutputError(f"{exc}; {directory.record} still says the run is unfinished",
                              exc.path) from exc
        _log.error("%s; %s still says the run is unfinished", exc, directory.record)


def _open_recording(directory: OutputDir, experiment: Experiment, started_utc: str) -> Any:
    """``run.mcap`` in the staging folder: it moves into ``--out`` with the other files, or
    stays there, readable up to its last sync, when the run is killed."""
    import json

    from hapticframe.record._recording import RECORDING, RunRecording

    return RunRecording(directory.staging / RECORDING, {
        "name": experiment.model.name, "seed": str(experiment.seed),
        "experiment_file": str(experiment.file), "started_utc": started_utc,
        # The scene, region and settings for report, view and replay.
        "config": json.dumps(experiment.resolved_config()),
    })


def _record_metrics(session: Session, metrics: dict[str, Any]) -> None:
    """``/metrics`` in ``run.mcap``: what ``metrics.json`` says and each component's own
    part of it (a replay carries the parts of components it does not rebuild)."""
    if session.recording is not None:
        session.recording.event("/metrics", "hapticframe.RunMetrics", {
            "metrics": metrics, "components": session.component_metrics})


def _close_recording(session: Session) -> OutputError | None:
    """Write the devices' last counters and the recording's summary; the error when the
    file cannot be written."""
    recording = session.recording
    if recording is None or recording.closed:
        return None
    try:
        try:
            health = _device_health(session.components)
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


def run_experiment(
    experiment: Experiment,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    echo: Callable[[str], None] | None = None,
    progress: bool = True,
    min_free_bytes: int | None = None,
) -> RunSummary:
    """Build and run ``experiment``, writing results into ``out_dir``.

    ``echo`` receives the progress lines (default: the ``hapticframe.run`` logger at INFO
    level); ``progress=False`` also asks the components to draw no progress bars of their
    own (``--quiet``). ``out_dir`` must have ``min_free_bytes`` free (default 50 MB, or
    ``HAPTICFRAME_MIN_FREE_MB``); with ``overwrite`` the results of an earlier run there
    are deleted first (only files its ``run.json`` lists).

    Returns
    -------
    RunSummary
        The metrics written to ``metrics.json``.

    Raises
    ------
    ExperimentError, UsageError
        Before anything is written (exit status 2): ``out_dir`` lies below a file, or holds
        results that ``overwrite`` may not (or was not asked to) replace.
    OutputError
        ``out_dir`` cannot be written or is short of space (before anything runs), or a
        result file cannot be written while running (naming the file; exit status 1).
    RunError
        When the run fails, or a component's ``close()`` raises; ``run.json`` then records
        the failure (exit status 1).
    RunInterrupted
        On Ctrl-C (SIGINT) or SIGTERM while running; ``run.json`` records
        ``status: interrupted`` and the signal (exit status 130 or 143).
    """
    directory = OutputDir.prepare(out_dir, overwrite=overwrite, min_free=min_free_bytes)
    out = directory.path
    say = echo if echo is not None else _log.info
    close_errors: list[str] = []

    def on_close_error(component_id: str, exc: BaseException) -> None:
        close_errors.append(f"closing {component_id!r} failed: {type(exc).__name__}: {exc}")

    started_utc = datetime.now(timezone.utc).isoformat(timespec="seconds")
    # Before anything is built: a run killed from here on leaves a run.json that says so.
    directory.begin(_running_record(experiment, started_utc))
    session: Session | None = None
    error: str | None = None
    signal_name: str | None = None
    metrics: dict[str, Any] = {}
    primary: BaseException | None = None
    recording_error: OutputError | None = None
    try:
        with _sigterm_as_interrupt(), ExitStack() as stack:
            components = _assembly.build_components(
                experiment, stack, progress=progress, on_close_error=on_close_error
            )
            # Every file of the run goes to the staging folder until the run ends.
            session = Session(experiment, directory.staging, components, say,
                              results_dir=out)
            session.started_utc = started_utc
            if session.settings.record:
                session.recording = _open_recording(directory, experiment, started_utc)
            try:
                session.hook.hapticframe_session_start(session=session.view())
                _fit_before_run(session)
                run_loop(session)
                metrics = score_run(session)
                if session.components.robots:
                    metrics["halt_latency_samples_max"] = _latency_metric(session)
                health = _device_health(components)
                if health:
                    metrics["devices"] = health
                _record_metrics(session, metrics)
                save_outputs(session, metrics)
                session.status = "ok"
            except DeviceError as exc:
                # Stop every actuator before anything else is released.
                halted, failures = _stop_robots(session, "device failure")
                session.status = "failed"
                error = f"device failure{_blame(exc, components)}: {exc}"
                if halted:
                    error += f" (halted {', '.join(repr(r) for r in halted)})"
                if failures:
                    error += "; " + "; ".join(failures)
                raise RunError(f"the run failed: {error}") from exc
            except RunInterrupted as exc:
                # As for a device failure: every actuator stops before anything is released.
                _stop_robots(session, "interrupted")
                session.status, signal_name, error = "interrupted", exc.signal_name, None
                raise
            except KeyboardInterrupt as exc:
                _stop_robots(session, "interrupted")
                session.status, signal_name = "interrupted", "SIGINT"
                raise RunInterrupted("SIGINT") from exc
            except HapticframeError as exc:
                session.status, error = "failed", str(exc)
                raise
            except Exception as exc:
                session.status = "failed"
                error = f"{type(exc).__name__}{_blame(exc, components)}: {exc}"
                raise RunError(f"the run failed: {error}") from exc
            finally:
                session.hook.hapticframe_session_finish(
                    session=session.view(), status=session.status
                )
        # The stack has closed every component by now.
    except BaseException as exc:
        primary = exc
        raise
    finally:
        if session is None:
            directory.discard()  # it failed to build: nothing was written
        else:
            if session.safety_halts:
                session.details["safety_halts"] = session.safety_halts
            if session.status != "ok":
                try:
                    health = _device_health(session.components)
                except Exception:  # a broken device's counters never hide the run's error
                    health = {}
                if health:
                    session.details["devices"] = health
            if close_errors and session.status == "ok":
                session.status, error = "failed", "; ".join(close_errors)
            elif close_errors:
                session.details["close_errors"] = close_errors
            recording_error = _close_recording(session)
            if recording_error is not None:
                if session.status == "ok":
                    session.status, error = "failed", str(recording_error)
                else:  # the run is already failing: its first error stays the error
                    session.details["recording_error"] = str(recording_error)
            wall = time.perf_counter() - session.started
            _finish(directory, run_record(session, wall, error, signal_name), primary)
    if recording_error is not None and primary is None:
        raise recording_error
    if close_errors:
        raise RunError("; ".join(close_errors))
    summary = RunSummary(metrics)
    summary.out_dir = out
    return summary
