"""``hapticframe run --live``: a run with its page, which stays up however the run ends.

After the run has finished, failed or been interrupted by Ctrl-C, the page keeps the last
picture with the run's status (and why it stopped) until the person presses Ctrl-C (again);
only then does the command report the run's error, as it would without ``--live``. SIGTERM
asks the process to go: the page goes with it at once.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from hapticframe._errors import HapticframeError, RunInterrupted
from hapticframe.live._server import LiveFeed, LiveServer

__all__ = ["evaluated_map", "run_live"]


def evaluated_map(experiment: Any) -> str | None:
    """The map the run will score (``Experiment.evaluated_map``): the page shows it first."""
    chosen: str | None = experiment.evaluated_map()
    return chosen


def _ending(exc: BaseException) -> tuple[str, str, bool]:
    """``(status, reason, keep the page)`` for a run that raised ``exc``."""
    if isinstance(exc, RunInterrupted):
        if exc.signal_name == "SIGINT":
            return "interrupted", "Ctrl-C (SIGINT)", True
        return "interrupted", exc.signal_name, False  # SIGTERM: the process is asked to go
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted", "Ctrl-C", True
    if isinstance(exc, HapticframeError):
        return "failed", str(exc), True
    if isinstance(exc, Exception):
        return "failed", f"{type(exc).__name__}: {exc}", True
    return "failed", type(exc).__name__, False  # SystemExit and the like: no waiting


def run_live(experiment: Any, run: Callable[[], Mapping[str, Any]], *, port: int,
             say: Callable[[str], None], wait: Callable[[], None],
             finished: Callable[[Mapping[str, Any]], None] | None = None,
             ) -> Mapping[str, Any]:
    """Serve the live page on ``port`` while ``run()`` runs the experiment, then keep it up.

    Parameters
    ----------
    experiment : ValidatedExperiment
        The experiment ``run`` runs (the page shows its evaluated map first).
    run : callable
        Runs it and returns its metrics (``run_experiment`` with the command's options).
    port : int
        The page's port on 127.0.0.1 (0: any free one; the address is told through ``say``).
    say : callable
        Prints one line for the person (the command's stdout).
    wait : callable
        Returns when the person is done with the page (the command: at Ctrl-C).
    finished : callable, optional
        Called with the metrics of a finished run before waiting (the command's summary).

    Returns
    -------
    Mapping
        The run's metrics.

    Raises
    ------
    UsageError
        When the page cannot be served (aiohttp missing, port taken), before the run.
    BaseException
        Whatever the run raised, once ``wait`` has returned (at once for SIGTERM).
    """
    feed = LiveFeed(preferred_map=evaluated_map(experiment))
    server = LiveServer(feed, port=port)
    say(f"live view: {server.start()} (Ctrl-C stops the run; the page stays up until the "
        "next Ctrl-C)")
    try:
        try:
            from hapticframe.record._recording import listening

            with listening(feed.listener):
                metrics = run()
        except BaseException as exc:
            status, reason, keep = _ending(exc)
            feed.end(status, reason=reason)
            if keep:
                say(f"live view: the run {status} ({reason.splitlines()[0] if reason else ''});"
                    f" the page shows its last picture at {server.url} until Ctrl-C")
                wait()
            raise
        feed.end("ok", dict(metrics))
        if finished is not None:
            finished(metrics)
        say(f"live view: the run has ended; the page stays at {server.url} until Ctrl-C")
        wait()
        return metrics
    finally:
        server.stop()
