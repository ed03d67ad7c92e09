"""``hapticframe import``: tabular trials (by a layout) as a recording sensors replay.

:func:`import_tables` reads every table with :func:`hapticframe.record._tables.read_trials` (all
of them checked before anything is written) and writes into ``DIR``:

- ``trace.npz``, in the layout of a run's trace (``trace-recording`` replays it, one trial
  per ``movement_index`` of the layout's robot): ``sensor/<sensor>/timestamps_s``, one array
  per channel *and per label* (``sensor/<sensor>/<name>`` with its ``/unit``), and
  ``robot/<robot>/timestamps_s``, ``movement_index`` (the trial) and ``position_m`` (n, 3)
  when the layout has positions; ``import/trial_names`` and ``import/trial_starts`` name
  the trials;
- ``run.mcap``, the same samples as ``/sensor/<sensor>`` ``SampleBatch`` messages (the
  ``recording`` sensor replays them) and the positions as ``/robot/<robot>/state``;
- ``import.json``: the source, the layout, the rate and its note, trials and steps.

Time: the layout's nominal ``rate_hz`` spaces a trial's steps; trial *j + 1* starts
:data:`TRIAL_GAP_S` after the last step of trial *j*, so times increase over the file and a
replay never joins two trials into one window.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe.record._tables import TableLayout, TableTrial, load_layout, read_trials

__all__ = ["TRIAL_GAP_S", "TableImport", "describe_import", "import_tables", "trace_arrays"]

#: Time between the last step of one trial and the first of the next.
TRIAL_GAP_S = 1.0


@dataclass(frozen=True)
class TableImport:
    """What :func:`import_tables` wrote."""

    source: Path
    out: Path
    trials: tuple[str, ...]
    steps: tuple[int, ...]
    channels: dict[str, str]
    rate_hz: float


def _trial_times(trials: Sequence[TableTrial], rate_hz: float) -> list[np.ndarray]:
    times, start = [], 0.0
    for trial in trials:
        t = start + np.arange(trial.steps, dtype=np.float64) / rate_hz
        times.append(t)
        start = float(t[-1]) + TRIAL_GAP_S
    return times


def trace_arrays(trials: Sequence[TableTrial], layout: TableLayout) -> dict[str, np.ndarray]:
    """The ``trace.npz`` arrays of ``trials`` (see the module's docstring)."""
    if not trials:
        raise ValueError("no trials to import")
    sensor, robot = f"sensor/{layout.sensor}", f"robot/{layout.robot}"
    t = np.concatenate(_trial_times(trials, layout.rate_hz))
    arrays: dict[str, np.ndarray] = {f"{sensor}/timestamps_s": t}
    for name, channel in layout.channels.items():
        arrays[f"{sensor}/{name}"] = np.concatenate([tr.channels[name] for tr in trials])
        arrays[f"{sensor}/{name}/unit"] = np.array(channel.unit)
    for name, label in layout.labels.items():
        arrays[f"{sensor}/{name}"] = np.concatenate([tr.labels[name] for tr in trials])
        arrays[f"{sensor}/{name}/unit"] = np.array(label.unit)
    arrays[f"{robot}/timestamps_s"] = t
    arrays[f"{robot}/movement_index"] = np.concatenate(
        [np.full(tr.steps, j, dtype=np.int64) for j, tr in enumerate(trials)])
    if layout.position is not None:
        arrays[f"{robot}/position_m"] = np.concatenate(
            [tr.position_m for tr in trials if tr.position_m is not None])
    arrays["import/trial_names"] = np.array([tr.name for tr in trials])
    arrays["import/trial_starts"] = np.cumsum([0] + [tr.steps for tr in trials[:-1]]
                                              ).astype(np.int64)
    return arrays


def _units(layout: TableLayout) -> dict[str, str]:
    return {**{n: c.unit for n, c in layout.channels.items()},
            **{n: lab.unit for n, lab in layout.labels.items()}}


def import_tables(source: str | Path, layout_path: str | Path, out_dir: str | Path, *,
                  overwrite: bool = False, min_free_bytes: int | None = None) -> TableImport:
    """Read ``source`` by the layout in ``layout_path`` and write the recording to ``out_dir``.

    Raises
    ------
    ExperimentError
        The layout file is invalid (file, line, dotted path; exit status 2).
    TableError
        A table does not match the layout (file, table, row, column; exit status 2).
    UsageError
        ``out_dir`` holds results ``overwrite`` may not replace (exit status 2).
    """
    from hapticframe.run._results import OutputDir, environment

    source = Path(source)
    layout = load_layout(layout_path)
    trials = read_trials(source, layout)  # every table checked before DIR is touched
    directory = OutputDir.prepare(out_dir, record="import.json", command="table import",
                                  overwrite=overwrite, min_free=min_free_bytes)
    record: dict[str, Any] = {
        "command": "import", "source": str(source), "layout": str(layout_path),
        "layout_resolved": layout.model_dump(mode="json"), "rate_hz": layout.rate_hz,
        "rate_note": layout.rate_note, "trials": [t.name for t in trials],
        "steps": [t.steps for t in trials], "versions": environment()}
    directory.begin(record)
    try:
        arrays = trace_arrays(trials, layout)
        np.savez_compressed(directory.staging / "trace.npz", **arrays)  # type: ignore[arg-type]
        _write_mcap(directory.staging / "run.mcap", arrays, layout, source)
        files = directory.commit(record)
        directory.finish({**record, "status": "ok"}, files)
    except BaseException:
        directory.discard()
        raise
    return TableImport(source, directory.path, tuple(t.name for t in trials),
                       tuple(t.steps for t in trials), _units(layout), layout.rate_hz)


def _write_mcap(path: Path, arrays: dict[str, np.ndarray], layout: TableLayout,
                source: Path) -> None:
    from hapticframe.kinds import RobotState, SampleBatch
    from hapticframe.record._recording import BLOCK_S, RunRecording

    sensor, robot = f"sensor/{layout.sensor}", f"robot/{layout.robot}"
    t = arrays[f"{sensor}/timestamps_s"]
    names = list(_units(layout))
    recording = RunRecording(path, {"name": f"import of {source.name}", "source": "import",
                                    "layout": layout.name, "tables": str(source),
                                    "sensors": json.dumps({layout.sensor: names})})
    units = _units(layout)
    rates = dict.fromkeys(names, layout.rate_hz)
    movement = arrays[f"{robot}/movement_index"]
    position = arrays.get(f"{robot}/position_m")
    try:
        edges = np.flatnonzero(np.diff(np.floor(t / BLOCK_S))) + 1
        for lo, hi in zip(np.r_[0, edges], np.r_[edges, t.size], strict=True):
            recording.samples("sensor", layout.sensor, SampleBatch(
                t[lo:hi], {n: arrays[f"{sensor}/{n}"][lo:hi] for n in names}), units, rates)
            if position is not None:
                for i in range(lo, hi):
                    step = position[i] - position[i - 1] if i and movement[i] == movement[
                        i - 1] else np.zeros(3)
                    heading = float(np.arctan2(step[1], step[0])) if step[:2].any() else 0.0
                    recording.robot_state(layout.robot, RobotState(
                        float(t[i]), position[i, :2], heading, float(position[i, 2])),
                        int(movement[i]))
    finally:
        recording.close()


def describe_import(result: TableImport) -> list[str]:
    """The lines ``hapticframe import`` prints."""
    steps = np.asarray(result.steps)
    return [
        f"read {len(result.trials)} trials from {result.source}: {steps.sum()} steps "
        f"({steps.min()}..{steps.max()} per trial) at a nominal {result.rate_hz:g} Hz",
        "channels: " + ", ".join(f"{n} [{u}]" for n, u in result.channels.items()),
        f"wrote {result.out / 'trace.npz'} (trace-recording) and {result.out / 'run.mcap'} "
        "(recording)",
    ]
