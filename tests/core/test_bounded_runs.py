"""Bounded by default (issue 34 §3): an open loop over a sensor that never ends states its
length (``run.duration_s``) or ``validate`` refuses it, saying what run.max_reads reads
would write; a run that stops at a limit is no result, with the limit named, never ``ok``."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main

SUPPORT = Path(__file__).resolve().parent.parent / "support"
PLUGIN = ("--plugin-module", "lab_newcomer")

SENSOR_ONLY = """\
schema_version: 1
name: sensor-only
seed: 1
sensors:
  - id: lab
    type: lab-fake-ft-clocked
run: {{figures: false{run}}}
"""


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(SUPPORT / "lab_newcomer.py", tmp_path / "lab_newcomer.py")
    monkeypatch.delitem(sys.modules, "lab_newcomer", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _file(lab_dir: Path, run: str, name: str = "e") -> Path:
    path = lab_dir / f"{name}.yaml"
    path.write_text(SENSOR_ONLY.format(run=run))
    return path


def test_an_unbounded_sensor_only_run_is_refused_at_validate_with_what_it_would_write(
    lab_dir, capsys
):
    assert main(["validate", *PLUGIN, str(_file(lab_dir, ""))]) == 2
    err = capsys.readouterr().err
    assert "e.yaml:7: run:" in err  # located at the run section
    assert "'lab', which never ends" in err and "1,000,000 reads" in err
    # One (3,) force sample a read: 8 B of time and 24 B of values, 10^6 times: 32 MB.
    assert "at least 32.0 MB" in err or "at least 30.5 MiB" in err, err
    assert "run.duration_s" in err


def test_a_stated_length_runs_that_long_on_the_runs_clock_and_ends_ok(lab_dir):
    path = _file(lab_dir, ", duration_s: 0.5")
    assert main(["validate", *PLUGIN, str(path)]) == 0
    out = lab_dir / "out"
    assert main(["run", *PLUGIN, str(path), "--out", str(out), "--quiet"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "ok" and record["details"]["sensor_reads"] == 50
    assert record["details"]["ended_by"].startswith("run.duration_s")
    times = np.load(out / "trace.npz")["sensor/lab/timestamps_s"]
    assert times.size == 50 and times[-1] == pytest.approx(0.5)


def test_a_run_stopped_by_run_max_reads_is_no_result_naming_the_limit(lab_dir, capsys):
    path = _file(lab_dir, ", duration_s: 10, max_reads: 20")
    out = lab_dir / "out"
    assert main(["run", *PLUGIN, str(path), "--out", str(out), "--quiet"]) == 1
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "failed" and "stopped at run.max_reads" in record["error"]
    assert record["details"]["limit"]["setting"] == "run.max_reads"
    assert record["details"]["sensor_reads"] == 20
    assert (out / "trace.npz").is_file() and (out / "metrics.json").is_file()
    assert "stopped at run.max_reads" in capsys.readouterr().err


def test_duration_s_is_refused_in_a_closed_loop(lab_dir, capsys):
    path = lab_dir / "closed.yaml"
    path.write_text(
        "schema_version: 1\nname: c\nseed: 1\nrobots:\n  - {id: arm, type: sandbox}\n"
        "sensors:\n  - {id: wrist, type: sandbox-force, inputs: [arm]}\n"
        "planners:\n  - {id: p, type: coverage}\nrun: {duration_s: 5}\n"
    )
    assert main(["validate", str(path)]) == 2
    assert "run.duration_s bounds an open loop" in capsys.readouterr().err
