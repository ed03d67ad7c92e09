"""``hapticframe.run_experiment``: a run recorded into ``run.mcap``.

The run layer (:func:`hapticframe.run._run.run_experiment`) writes its recording through
whatever :class:`~hapticframe.run._channels.RecordingOpener` it is handed and never imports
the writer; this facade hands it ``run.mcap``'s (:func:`~hapticframe.record._recording.
open_run_recording`), as the CLI and the sweep's trials do.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from hapticframe._config import Experiment
from hapticframe.record._recording import open_run_recording
from hapticframe.run import _run
from hapticframe.run._channels import RecordingOpener
from hapticframe.run._results import RunSummary

__all__ = ["run_experiment"]


def run_experiment(
    experiment: Experiment,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    echo: Callable[[str], None] | None = None,
    progress: bool = True,
    min_free_bytes: int | None = None,
    recording: RecordingOpener | None = open_run_recording,
) -> RunSummary:
    """Build and run ``experiment``, writing results into ``out_dir`` and, when
    ``run.record`` is on, the recording ``run.mcap`` (``recording``: the writer's opener;
    None records nothing).

    Everything else is :func:`hapticframe.run._run.run_experiment`'s: see it for the
    options, the results and the errors.
    """
    return _run.run_experiment(experiment, out_dir, overwrite=overwrite, echo=echo,
                               progress=progress, min_free_bytes=min_free_bytes,
                               recording=recording)
