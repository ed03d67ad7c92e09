"""``hapticframe report``: trace.npz and figures from a recording, a recovered one included."""

from __future__ import annotations

import json
import os
import shutil

import numpy as np
import pytest

from hapticframe._lock import LOCK_FILE, lock_directory
from hapticframe.cli._cli import main
from hapticframe.kinds import SampleBatch
from hapticframe.record._recording import RECORDING, RunRecording
from hapticframe.record._report import (
    load_recording,
    paths_figure,
    signals_figure,
    trace_arrays,
    truth_of,
)
from hapticframe.run._results import STAGING
from tests.core import test_recording_snapshots

#: The short search, run once per session (a fixture shared with the snapshot tests).
short_search = test_recording_snapshots.short_search

FIGURES = {"report_map_grid_mean.png", "report_map_grid_std.png", "report_map_bhm_mean.png",
           "report_map_bhm_std.png", "report_paths.png", "report_signals.png"}


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return (a.dtype == b.dtype and a.shape == b.shape
            and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


def test_the_report_rebuilds_the_runs_trace(short_search, tmp_path, capsys):
    out = tmp_path / "report"
    assert main(["report", str(short_search), "--out", str(out)]) == 0
    assert f"into {out}" in capsys.readouterr().out
    ours, theirs = np.load(out / "report_trace.npz"), np.load(short_search / "trace.npz")
    assert sorted(ours.files) == sorted(theirs.files)
    for key in theirs.files:
        assert _same(ours[key], theirs[key]), key
    for name in FIGURES:
        assert (out / name).read_bytes().startswith(b"\x89PNG"), name


def test_the_report_goes_beside_the_runs_results_and_is_listed(short_search, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(short_search, run)
    before = {name: (run / name).read_bytes() for name in ("trace.npz", "metrics.json")}
    assert main(["report", str(run), "--no-figures"]) == 0
    files = json.loads((run / "run.json").read_text())["files"]
    assert "report_trace.npz" in files and "trace.npz" in files
    # The run's own results are never written over: the report's trace lies beside them.
    assert {name: (run / name).read_bytes() for name in before} == before
    assert _same(np.load(run / "report_trace.npz")["robot/arm/position_m"],
                 np.load(short_search / "trace.npz")["robot/arm/position_m"])
    assert not (run / LOCK_FILE).exists()  # the lock is let go


def test_a_recording_of_another_run_is_not_reported_into_a_run(short_search, tmp_path,
                                                               capsys):
    """Issue 26 §1: another experiment's run.mcap copied into a run is refused, and the
    run's trace.npz and metrics.json stay as they were."""
    run = tmp_path / "run"
    shutil.copytree(short_search, run)
    record = json.loads((run / "run.json").read_text())
    record["started_utc"] = "2020-01-01T00:00:00+00:00"  # another run of the same file
    (run / "run.json").write_text(json.dumps(record))
    before = sorted((p.name, p.read_bytes()) for p in run.iterdir())
    assert main(["report", str(run)]) == 2
    err = capsys.readouterr().err
    assert "is not the recording of the run in" in err and "started_utc" in err
    assert "Traceback" not in err
    assert sorted((p.name, p.read_bytes()) for p in run.iterdir()) == before


def test_a_report_waits_for_no_one(short_search, tmp_path, capsys):
    """Issue 26 §2: a directory another command writes into is refused at once, naming it."""
    run = tmp_path / "run"
    shutil.copytree(short_search, run)
    with lock_directory(run, "run"):
        assert main(["report", str(run), "--no-figures"]) == 2
    err = capsys.readouterr().err
    assert f"is in use by run (pid {os.getpid()}, started " in err
    assert not (run / "report_trace.npz").exists()


def test_a_killed_runs_recording_is_reported_up_to_its_cut(short_search, tmp_path, capsys):
    killed = tmp_path / "killed"
    (killed / STAGING).mkdir(parents=True)
    data = (short_search / RECORDING).read_bytes()
    (killed / STAGING / RECORDING).write_bytes(data[:int(len(data) * 0.6)])
    assert main(["report", str(killed), "--no-figures"]) == 0
    assert "cut short" in capsys.readouterr().out
    ours, theirs = np.load(killed / "report_trace.npz"), np.load(short_search / "trace.npz")
    for key in ("robot/arm/timestamps_s", "sensor/wrist/force_n", "classifier/jamming/"
                "probabilities"):
        n = len(ours[key])
        assert 0 < n < len(theirs[key])
        assert _same(ours[key], theirs[key][:n]), key  # a prefix, exactly
    # And after `hapticframe recover`, the same.
    assert main(["recover", str(killed)]) == 0
    assert main(["report", str(killed), "--out", str(tmp_path / "recovered")]) == 0
    assert (tmp_path / "recovered" / "report_paths.png").is_file()
    for key in ours.files:
        assert _same(np.load(tmp_path / "recovered" / "report_trace.npz")[key], ours[key]), key


def test_the_figures_draw_every_legend_entry_and_the_truth(short_search):
    recording = load_recording(short_search / RECORDING)
    outlines, region = truth_of(recording)
    assert region == pytest.approx((0.0, 0.75, 0.0, 0.5))
    [ellipse] = outlines
    assert ellipse.mean(axis=0) == pytest.approx([0.42, 0.21], abs=1e-3)
    figure = paths_figure(recording, (outlines, region))
    assert figure is not None
    labels = {t.get_text() for t in figure.legends[0].get_texts()}
    assert labels == {"search region", "true object", "fingertip path (arm)",
                      "planned movements", "halted: interaction"}
    signals = signals_figure(recording)
    assert signals is not None
    force, probabilities = signals.axes
    assert {t.get_text() for t in force.get_legend().get_texts()} == {
        "|wrist force_n|", "movement halted"}
    assert {t.get_text() for t in probabilities.get_legend().get_texts()} == {
        "P(free)", "P(jamming)", "P(contact)", "movement halted"}


def test_the_truth_comes_from_the_recorded_config_first(tmp_path):
    config = {"scene": {"region": {"x_min_m": 0.0, "x_max_m": 0.3, "y_min_m": 0.0,
                                   "y_max_m": 0.2},
                        "objects": [{"shape": "circle", "center_m": [0.1, 0.1],
                                     "radius_m": 0.02}]}}
    recording = RunRecording(tmp_path / "a.mcap", {"name": "x", "config": json.dumps(config)})
    batch = SampleBatch(np.array([0.0, 0.01]), {
        "force_n": np.array([[1.0, np.nan], [2.0, 3.0]]), "contact": np.array([0.0, 1.0])})
    recording.samples("sensor", "s", batch, {"force_n": "N"})
    recording.close()
    loaded = load_recording(tmp_path / "a.mcap")
    [circle], region = truth_of(loaded)
    assert region == (0.0, 0.3, 0.0, 0.2)
    np.testing.assert_allclose(np.hypot(*(circle - 0.1).T), 0.02)
    # NaN and whole numbers come back as the recorder kept them.
    trace = trace_arrays(loaded)
    for name, array in batch.channels.items():
        assert _same(trace[f"sensor/s/{name}"], array), name
    assert str(trace["sensor/s/force_n/unit"]) == "N"


def test_what_is_not_a_recording_is_refused(tmp_path, capsys):
    bogus = tmp_path / "run.mcap"
    bogus.write_bytes(b"not a recording")
    assert main(["report", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"{bogus} is not an MCAP recording" in err and "Traceback" not in err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["report", str(empty)]) == 2
    assert "holds no recording" in capsys.readouterr().err
    RunRecording(empty / RECORDING).close()
    assert main(["report", str(empty)]) == 2
    assert "holds no messages" in capsys.readouterr().err
