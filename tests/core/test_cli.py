"""The command line: exit codes, outputs of a run, and what it refuses."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main
from tests.support.lab import lab_main


def test_run_writes_results_metadata_and_trace(lab_dir, capsys):
    out = lab_dir / "run"
    assert lab_main(["run", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["object_found"] is True and metrics["centroid_error_m"] < 0.01
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "ok" and record["seed"] == 3
    assert record["resolved_config"]["sensors"][0]["config"]["chunk"] == 20
    assert {p["type"] for p in record["plugins"]} == {
        "lab-sweep", "lab-threshold", "lab-point", "lab-cells"}
    assert record["plugins"][0]["distribution"] == "<plugin-module>"
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        assert trace["sensor/sweep/force_n"].shape == (300, 2)
        assert trace["classifier/contact/probabilities"].shape == (300, 2)
        assert trace["sensor_model/point/targets"].shape == (300,)


def test_runs_are_reproducible(lab_dir):
    first, second = lab_dir / "a", lab_dir / "b"
    experiment = str(lab_dir / "lab-open-loop.yaml")
    for out in (first, second):
        assert lab_main(["run", experiment, "--out", str(out), "--quiet"]) == 0
    with np.load(first / "trace.npz") as a, np.load(second / "trace.npz") as b:
        assert set(a.files) == set(b.files)
        for key in a.files:
            assert np.array_equal(a[key], b[key])


def test_run_refuses_to_overwrite_a_previous_run(lab_dir, capsys):
    out = lab_dir / "run"
    args = ["run", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out), "--quiet"]
    assert lab_main(args) == 0
    before = (out / "run.json").read_text()
    assert lab_main(args) == 2
    assert "already holds a run" in capsys.readouterr().err
    assert (out / "run.json").read_text() == before
    assert lab_main([*args, "--overwrite"]) == 0


def test_failure_while_running_exits_1_and_records_it(lab_dir, capsys):
    path = lab_dir / "lab-open-loop.yaml"
    # Valid, and it builds; but the extractor's gain overflows the forces to infinity,
    # which the classifier refuses only once samples flow.
    text = path.read_text().replace(
        "classifiers:\n",
        "feature_extractors:\n  - {id: gain, type: lab-scale, inputs: [sweep], "
        "config: {factor: 1.0e+308}}\nclassifiers:\n",
    ).replace("    inputs: [sweep]\nsensor_models", "    inputs: [gain]\nsensor_models")
    broken = lab_dir / "norun.yaml"
    broken.write_text(text)
    out = lab_dir / "run"
    assert lab_main(["run", str(broken), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "must be finite" in err and "Traceback" not in err
    assert json.loads((out / "run.json").read_text())["status"] == "failed"


def test_debug_shows_the_traceback(lab_dir, capsys):
    args = ["run", str(lab_dir / "missing.yaml"), "--out", str(lab_dir / "o")]
    assert lab_main(args) == 2
    assert "no such file" in capsys.readouterr().err
    with pytest.raises(Exception, match="no such file"):
        main(["--debug", *args])


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as info:
        lab_main(["run"])
    assert info.value.code == 2
    assert main([]) == 2
    assert main(["bench", "no-such-suite"]) == 2
    assert "unknown benchmark" in capsys.readouterr().err


def test_check_command_runs_the_kit(lab_dir, capsys, monkeypatch):
    assert main(["check", "no-such-plugin"]) == 2
    assert main(["check", "bayesian-hilbert-mapp"]) == 2
    assert "did you mean 'bayesian-hilbert-map'?" in capsys.readouterr().err


def test_python_dash_m_and_version():
    proc = subprocess.run([sys.executable, "-m", "hapticframe", "--version"],
                          capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.startswith("hapticframe ")


def test_session_hooks_and_run_metadata_reach_lab_plugins(lab_dir):
    out = lab_dir / "run"
    assert lab_main(["run", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out), "--quiet"]) == 0
    labplugin = sys.modules["labplugin"]  # imported by --plugin-module
    assert labplugin.SESSIONS[-2:] == [("start", "lab-open-loop"), ("finish", "ok")]
    record = json.loads((out / "run.json").read_text())
    assert record["plugin_metadata"] == {"lab_rig": "sandbox-2"}


def test_a_known_plugin_with_missing_requirements_gets_its_install_hint(lab_dir, capsys):
    path = lab_dir / "lab-open-loop.yaml"
    path.write_text(path.read_text().replace("type: lab-sweep", "type: lab-needs-driver"))
    assert lab_main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "needs no_such_vendor_driver" in err and "pip install lab-vendor-driver" in err
    assert f"{path}:11:" in err


def test_train_fits_classifiers_on_labelled_recordings_and_saves(lab_dir, capsys):
    out = lab_dir / "trained"
    assert lab_main(["train", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out)]) == 0
    record = json.loads((out / "train.json").read_text())
    assert record["trained"] == ["contact"] and record["recordings"] == 1
    threshold = json.loads((out / "contact" / "threshold.json").read_text())["threshold_n"]
    # Free force is ~5 N and contact ~35-45 N: the learned threshold lies between.
    assert 10 < threshold < 40 and record["reports"]["contact"]["threshold_n"] == threshold
    assert lab_main(["train", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out)]) == 2
    path = lab_dir / "lab-open-loop.yaml"
    path.write_text(path.read_text().replace("seed: 3", "seed: 3\nrun: {label_channel: nothing}"))
    assert lab_main(["train", str(path), "--out", str(lab_dir / "t2")]) == 1
    assert "no label channel 'nothing'" in capsys.readouterr().err


def test_quiet_asks_every_component_to_draw_no_progress_bar(lab_dir, monkeypatch):
    import hapticframe.run._assembly as assembly

    seen: list[set[bool]] = []
    build = assembly.build_components

    def spy(experiment, stack, **kwargs):
        built = build(experiment, stack, **kwargs)
        seen.append({component.context.progress for component in built.values()})
        return built

    monkeypatch.setattr(assembly, "build_components", spy)
    experiment = str(lab_dir / "lab-open-loop.yaml")
    for flags, expected in (([], True), (["--quiet"], False)):
        out = lab_dir / f"run-{len(seen)}"
        assert lab_main(["run", experiment, "--out", str(out), *flags]) == 0
        assert seen[-1] == {expected}


def test_hooks_receive_a_read_only_public_session_view(lab_dir):
    from hapticframe import SessionView

    out = lab_dir / "run"
    assert lab_main(["run", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out), "--quiet"]) == 0
    view = sys.modules["labplugin"].SEEN_SESSIONS[-1]
    assert isinstance(view, SessionView)
    assert view.name == "lab-open-loop" and view.out_dir == out and view.status == "ok"
    assert set(view.components) == {"sweep", "contact", "point", "cells"}
    with pytest.raises(TypeError):
        view.components["extra"] = view.components["sweep"]  # type: ignore[index]


def test_a_closed_pipe_ends_a_command_quietly():
    # `hapticframe schema | head -1`: the reader goes away after one line.
    proc = subprocess.run(
        f"{sys.executable} -m hapticframe schema | head -1", shell=True, capture_output=True,
        text=True, timeout=60,
    )
    assert proc.stdout.strip() == "{"
    assert "BrokenPipeError" not in proc.stderr and "error" not in proc.stderr


def test_main_leaves_the_process_warning_display_and_logging_as_it_found_them(lab_dir):
    import logging
    import warnings

    before = warnings.showwarning
    handlers = list(logging.getLogger("hapticframe").handlers)
    assert main(["plugins"]) == 0
    assert warnings.showwarning is before
    assert logging.getLogger("hapticframe").handlers == handlers
    assert any(isinstance(h, logging.NullHandler) for h in handlers)  # a library's default


def test_the_library_logs_and_the_cli_prints_its_warnings(lab_dir, capsys):
    import logging

    assert main(["plugins"]) == 0  # the CLI's handler is in place only while main runs
    capsys.readouterr()
    logging.getLogger("hapticframe.test").warning("outside a command")
    assert "outside a command" not in capsys.readouterr().err

    from hapticframe.cli import _plugins
    original = _plugins.cmd_plugins

    def noisy(args):  # type: ignore[no-untyped-def]
        logging.getLogger("hapticframe.test").warning("the port is slow")
        return original(args)

    try:
        _plugins.cmd_plugins = noisy
        parser_default = main(["plugins"])
    finally:
        _plugins.cmd_plugins = original
    assert parser_default == 0
    assert "warning: the port is slow" in capsys.readouterr().err


def test_the_run_summary_keeps_the_few_figures_a_person_reads(lab_dir, capsys):
    out = lab_dir / "run"
    assert lab_main(["run", str(lab_dir / "lab-open-loop.yaml"), "--out", str(out)]) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    metrics = json.loads((out / "metrics.json").read_text())
    assert line.startswith(f"results in {out} (all metrics in metrics.json): ")
    assert "centroid_error_m=" in line and "object_found=yes" in line
    assert "contact_balanced_accuracy=" in line
    # The largest force on the console is the one metrics.json records.
    assert f"max_measured_force_n={metrics['max_measured_force_n']:.4g}" in line
    assert "contact_frames" not in line and "contact_frames" in metrics  # the rest stays there


def test_a_run_without_a_search_prints_no_movement_count():
    from hapticframe.cli._common import summary_line

    perception = {"movements": 0, "contact_balanced_accuracy": 0.93, "wall_time_s": 31.0}
    search = {"movements": 0, "object_found": False, "wall_time_s": 2.0}
    assert "movements" not in summary_line(perception)
    assert "contact_balanced_accuracy=0.93" in summary_line(perception)
    assert summary_line(search).startswith("movements=0, object_found=no")
    # The perception example scores its belief map against a scene (object_found), yet
    # plans no movement: its line counts none.
    scored = {"movements": 0, "object_found": True, "contact_balanced_accuracy": 0.9}
    assert "movements" not in summary_line(scored, searched=False)
    # An object estimator's scores are printed (the raking example), before the wall time.
    raking = {"estimator_distance_mae_mm": 18.24, "estimator_direction_accuracy": 0.41,
              "estimator_depth_accuracy": 0.6, "estimator_replaced_samples": 0,
              "wall_time_s": 3.0}
    assert summary_line(raking, searched=False) == (
        "estimator_distance_mae_mm=18.24, estimator_direction_accuracy=0.41, "
        "estimator_depth_accuracy=0.6, wall_time_s=3")


def test_only_an_experiment_with_a_planner_counts_movements():
    from hapticframe import validate_file
    from hapticframe.cli._common import searches

    examples = Path(__file__).resolve().parents[2] / "examples"
    assert searches(validate_file(examples / "search-ellipse.yaml"))
    assert not searches(validate_file(examples / "perception-belief-map.yaml"))
    assert not searches(validate_file(examples / "raking-real.yaml"))


def test_check_says_what_it_checks_before_each_result(capsys):
    assert main(["check", "occupancy-grid"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("[1/1] map/occupancy-grid: ") and lines[0].endswith(" checks")
    count = int(lines[0].split(": ")[1].split()[0])
    results = [line for line in lines[1:-1] if line.startswith("PASS ")]
    assert len(results) == count and all(line.endswith(" s)") for line in results)
    assert lines[-1] == "all checks passed"
