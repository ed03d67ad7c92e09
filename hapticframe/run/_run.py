"""``hapticframe run``: one experiment from validated file to written results.

The orchestrator. It calls, in this order and never the other way round:
:mod:`~hapticframe.run._assembly` (build the components under one exit stack),
:mod:`~hapticframe.run._train` (fit before the run, ``run.train_from``),
:mod:`~hapticframe.run._loop` (the closed or open loop), :mod:`~hapticframe.run._evaluate`
(score the run) and :mod:`~hapticframe.run._results` (write ``trace.npz``, ``metrics.json`` and
``run.json``).

The output directory's life is the run scope's (:func:`~hapticframe.run._scope.run_scope`,
shared with replay and train): ``--out`` is checked and locked before anything is built (a
directory, writable, enough free space, no results it may not replace, no other command
writing there); ``run.json`` then says ``status: running`` until the run ends, and every
file is written atomically into a staging folder that moves into ``--out`` at the end, so a
run killed at any point leaves a directory that says it is unfinished. An experiment that
fails to build writes nothing. The recording (``run.mcap``) is written through the
:class:`~hapticframe.run._channels.RecordingOpener` the caller hands in (the CLI and
:func:`hapticframe.run_experiment` hand in ``run.mcap``'s writer); without one, the run
records nothing.

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
from collections.abc import Callable
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from hapticframe._config import Experiment
from hapticframe.run import _assembly
from hapticframe.run._channels import RecordingOpener
from hapticframe.run._evaluate import score_run
from hapticframe.run._loop import run_loop
from hapticframe.run._results import RunSummary, environment
from hapticframe.run._safety import FORCE_LIMIT
from hapticframe.run._scope import device_health, run_scope
from hapticframe.run._session import Session
from hapticframe.run._train import fit_before_run
from hapticframe.run._verdict import RunInconclusive, inconclusive_reasons

__all__ = ["RunSummary", "run_experiment"]

_log = logging.getLogger("hapticframe.run")


def _latency_metric(session: Session) -> int | None:
    """The largest halt latency of the run's force-limit halts (robot steps), or None."""
    latencies = [int(h["latency_samples"]) for h in session.safety_halts
                 if h.get("reason") == FORCE_LIMIT]
    return max(latencies) if latencies else None


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


def run_experiment(
    experiment: Experiment,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    echo: Callable[[str], None] | None = None,
    progress: bool = True,
    min_free_bytes: int | None = None,
    recording: RecordingOpener | None = None,
) -> RunSummary:
    """Build and run ``experiment``, writing results into ``out_dir``.

    ``echo`` receives the progress lines (default: the ``hapticframe.run`` logger at INFO
    level); ``progress=False`` also asks the components to draw no progress bars of their
    own (``--quiet``). ``out_dir`` must have ``min_free_bytes`` free (default 50 MB, or
    ``HAPTICFRAME_MIN_FREE_MB``); with ``overwrite`` the results of an earlier run there
    are deleted first (only files its ``run.json`` lists). ``recording`` opens the run's
    recording when ``run.record`` is on (:func:`hapticframe.run_experiment` passes
    ``run.mcap``'s writer; None: nothing is recorded).

    Returns
    -------
    RunSummary
        The metrics written to ``metrics.json``.

    Raises
    ------
    ExperimentError, UsageError
        Before anything is written (exit status 2): ``out_dir`` lies below a file, holds
        results that ``overwrite`` may not (or was not asked to) replace, or another
        command writes into it now.
    OutputError
        ``out_dir`` cannot be written or is short of space (before anything runs), or a
        result file cannot be written while running (naming the file; exit status 1).
    RunError
        When the run fails, or a component's ``close()`` raises; ``run.json`` then records
        the failure (exit status 1).
    RunInconclusive
        (a :class:`RunError`) The run ended but its figures are no result: its sensors
        delivered (almost) nothing, or a safety check halted every movement. Its files are
        written; ``run.json`` says ``failed`` and why (exit status 1).
    RunInterrupted
        On Ctrl-C (SIGINT) or SIGTERM while running; ``run.json`` records
        ``status: interrupted`` and the signal (exit status 130 or 143).
    """
    say = echo if echo is not None else _log.info
    started_utc = datetime.now(timezone.utc).isoformat(timespec="seconds")
    metrics: dict[str, Any] = {}
    with run_scope(out_dir, _running_record(experiment, started_utc), what="run",
                   overwrite=overwrite, min_free_bytes=min_free_bytes,
                   started_utc=started_utc) as scope:
        components = scope.build(lambda stack, on_close_error: _assembly.build_components(
            experiment, stack, progress=progress, on_close_error=on_close_error))
        # Every file of the run goes to the staging folder until the run ends.
        session = scope.start_session(experiment, say, recording=recording)
        fit_before_run(session)
        run_loop(session)
        metrics = score_run(session)
        if session.components.robots:
            metrics["halt_latency_samples_max"] = _latency_metric(session)
        health = device_health(components)
        if health:
            metrics["devices"] = health
        scope.save(metrics)
        reasons = inconclusive_reasons(session)
        if reasons:
            # Every file is kept for inspection; run.json says failed, and why.
            session.details["no_result"] = reasons
            raise RunInconclusive(reasons, metrics)
    summary = RunSummary(metrics, scope.out)
    return summary
