"""``hapticframe bench perception`` on a tiny plan: files, keys, shapes and ranges."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("sklearn")

import hapticframe
from hapticframe import BenchOptions
from hapticframe_bench._perception import (
    ALL,
    ARCHITECTURES,
    PERCEPTION_TARGETS,
    SuitePlan,
    _key,
    plan_for,
    run_perception,
)
from hapticframe_bench._perception_data import split_cottonwood, stage_inputs
from hapticframe_bench._perception_jobs import model_digest

SFRNN = "(d)+RNN (SF-RNN)"
ALL_KEY = "pac+pdc+electrodes"

# Everything small: 12 cottonwood trials, one trial per medium, a cheap EMD, tiny networks,
# one seed (averaging over seeds and resuming are tested on their own, below).
TINY = SuitePlan(
    cottonwood_trials=12, robustness_per_medium=1, seeds=1, max_epochs=1, patience=1,
    latency_frames=40, coder_fit_frames=600, quick=True,
    rnn_settings={"batch_size": 64, "free_stride_frames": 60, "contact_stride_frames": 30,
                  "window_frames": 20, "gru_layers": 1, "gru_units": 8, "fusion_units": 8,
                  "branch_layers": 1, "branch_units": 8},
    emd_settings={"max_sifts": 2, "delay_frames": 1},
    svm_settings={"calibration_folds": 2, "max_iter": 200},
    coder_settings={"fit_epochs": 1, "pac_atoms": 16, "pdc_atoms": 8, "electrodes_atoms": 8,
                    "encode_max_iter": 100},
    modality_sets=(("electrodes",), ("pac", "pdc", "electrodes")),
)


def _fractions(value):
    assert math.isfinite(value) and 0.0 <= value <= 1.0, value


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("perception")
    lines: list[str] = []
    headline = run_perception(BenchOptions(out_dir=out, seed=1, quick=True, workers=1,
                                           echo=lines.append), plan=TINY)
    return out, headline, lines


def test_tiny_run_writes_json_markdown_figure_and_model(tiny_run):
    out, headline, lines = tiny_run
    result = json.loads((out / "perception.json").read_text())
    for key in ("sfrnn_test_accuracy", "latency_ms_median", "latency_ms_p99", "tables"):
        assert key in result
    assert headline["sfrnn_test_accuracy"] == result["sfrnn_test_accuracy"]
    _fractions(result["sfrnn_test_accuracy"])
    assert 0 < result["latency_ms_median"] <= result["latency_ms_p99"] < 10_000
    assert result["latency"]["frames"] == TINY.latency_frames
    assert set(result["latency"]["stages_ms_median"]) == {"emd", "coding", "sfrnn"}
    tables = result["tables"]
    assert set(tables) == {"table_2_2", "table_2_3", "table_2_4", "table_2_4_conditions",
                           "table_a_1"}
    labels = {a.label for a in ARCHITECTURES}
    assert set(tables["table_2_2"]) == {"electrodes"}
    assert set(tables["table_2_3"]) == {"pac+pdc+electrodes"}
    for table in (tables["table_2_2"], tables["table_2_3"]):
        for row in table.values():
            assert set(row) == labels
            for cell in row.values():
                for split in ("train", "validation", "test"):
                    _fractions(cell[split]["mean"])
                    assert cell[split]["n"] == TINY.seeds and cell[split]["std"] >= 0
                assert 0 < cell["step_ms"] < 10_000
    assert set(tables["table_2_4"]) == labels
    for per in tables["table_2_4"].values():
        assert set(per) == {"poppy_seed", "plastic_pellets", "bbs", "pine_beads",
                            "cottonwood_beads"}
        for cell in per.values():
            _fractions(cell["mean"])
    # Table 2.4's own comparison (SF-RNN against the (d)+Linear SVM) per medium, and the
    # wider one against all five other models.
    sf, svm_d = tables["table_2_4"]["(d)+RNN (SF-RNN)"], tables["table_2_4"]["(d)+Linear SVM"]
    assert result["table_2_4_sfrnn_ahead"] == {m: sf[m]["mean"] > svm_d[m]["mean"] for m in sf}
    for medium, ahead in result["sfrnn_ahead_on_every_medium"].items():
        assert ahead == all(sf[medium]["mean"] > per[medium]["mean"]
                            for label, per in tables["table_2_4"].items() if per is not sf)
    # Table 2.4 by condition groups the same predictions: every trial falls in one pose and
    # one object place, and with one trial per medium the medium's only pose group scores
    # exactly what its Table 2.4 cell does.
    conditions = tables["table_2_4_conditions"]
    assert set(conditions) == labels
    for label, breakdown in conditions.items():
        for grouping in ("orientation_deg", "object_offset_m"):
            assert sum(g["trials"]["mean"] for g in breakdown[grouping].values()) == 5
        assert set(breakdown["orientation_deg"]) <= {"0", "20"}
        assert set(breakdown["object_offset_m"]) <= {"0", "0.035"}
        assert set(breakdown["medium_orientation_deg"]) == set(tables["table_2_4"][label])
        for medium, per_pose in breakdown["medium_orientation_deg"].items():
            (group,) = per_pose.values()
            assert group["balanced_accuracy"]["mean"] == pytest.approx(
                tables["table_2_4"][label][medium]["mean"])
            assert group["balanced_accuracy"]["n"] == TINY.seeds
            _fractions(group["contact_recall"]["mean"])
            assert 0 <= group["missed_contacts"]["mean"] <= group["contact_trials"]["mean"] == 1
    # Table A.1: the three-modality SF-RNN tested with all 7 subsets, the unimodal one with 1.
    assert len(tables["table_a_1"]["pac+pdc+electrodes"]) == 7
    assert list(tables["table_a_1"]["electrodes"]) == ["electrodes"]
    assert result["dataset"]["trials"]["robustness"] == 5
    # Recurrent models train on the training split and stop early on the validation split,
    # given to them (not a random hold-out drawn from train + validation).
    diagnostics = result["training"]["sfrnn_all_modalities"]
    assert len(diagnostics) == TINY.seeds
    for diag in diagnostics:
        assert diag["validation_source"] == "given"
        assert diag["train_trials"] == result["dataset"]["trials"]["train"]
        assert diag["validation_trials"] == result["dataset"]["trials"]["validation"]
    md = (out / "perception.md").read_text()
    for title in ("Table 2.2", "Table 2.3", "Table 2.4", "Table A.1", "98.7", "p99"):
        assert title in md
    # Table 2.4 puts the thesis's two (d) models first, then the rest below a marker row.
    section = md[md.index("## Table 2.4"):md.index("## Table 2.4 by condition")]
    rows = [line.split(" | ")[0].lstrip("| ") for line in section.splitlines()
            if line.startswith("| (")]
    assert rows[:2] == ["(d)+Linear SVM", "(d)+RNN (SF-RNN)"] and len(rows) == 6
    assert section.index("*beyond the thesis's table*") > section.index("| (d)+RNN (SF-RNN)")
    by_condition = md[md.index("## Table 2.4 by condition"):md.index("## Table A.1")]
    assert sum(line.startswith("| (") for line in by_condition.splitlines()) == 6
    assert sum(line.startswith("| Poppyseeds") for line in by_condition.splitlines()) == 1
    # Table A.1 as the appendix's grid: the three-modality block has one row per subset.
    block = md[md.index("SF-RNN trained with 3 modalities"):md.index("## SF-RNN training")]
    grid = [line for line in block.splitlines()[2:] if line.startswith("| ")]
    assert len(grid) == 7 and grid[-1].startswith("| vibration, fluid pressure, electrode")
    assert (out / "perception.png").stat().st_size > 1000
    assert (out / "sfrnn-model" / "model.json").is_file()
    assert any("SF-RNN test" in line for line in lines)
    # Each target beside its measurement with a verdict, in the JSON, the report and the lines.
    assert set(result["targets"]) == {t.name for t in PERCEPTION_TARGETS}
    assert result["table_2_4_media_sfrnn_ahead"] == sum(result["table_2_4_sfrnn_ahead"].values())
    for name, record in result["targets"].items():
        assert record["value"] == pytest.approx(result[name])
        above = record["value"] >= record["limit"]
        assert record["met"] is (above if record["comparison"] == ">=" else
                                 record["value"] <= record["limit"])
        verdict = "met" if record["met"] else "missed"
        assert sum(line.startswith(record["label"] + ": ") and line.endswith(f"  {verdict}")
                   for line in lines) == 1, lines
        assert f"| {record['label']} |" in md
    assert result["targets_met"] is all(r["met"] for r in result["targets"].values())


def test_the_tiny_run_keeps_each_job_with_its_fingerprint(tiny_run):
    out, _, _ = tiny_run
    first = json.loads((out / "perception.json").read_text())
    assert first["dataset"]["tare_source"] == "air"
    jobs = sorted((out / "jobs").glob("*.json"))
    assert [p.name for p in jobs] == ["seed0-electrodes.json", "seed0-pac+pdc+electrodes.json"]
    kept = json.loads(jobs[1].read_text())
    assert len(kept["fingerprint"]) == 64
    assert kept["result"]["model_sha256"] == model_digest(out / "sfrnn-model")


def _fake_job(calls):
    """A job runner that records its calls and saves a 'model' as the real one does."""
    def run(job):
        s, mods, seed, _rnn, _svm, save_dir = job
        calls.append((s, _key(mods)))
        result = {"seed_index": s, "modalities": mods, "score": 10 * s + len(mods) + seed,
                  "cells": {SFRNN: {"validation": 0.5, "test": 0.25 * len(mods)}}}
        if save_dir is not None and s == 0 and mods == ALL:
            Path(save_dir).mkdir(parents=True, exist_ok=True)
            (Path(save_dir) / "model.json").write_text("{}")
            (Path(save_dir) / "weights.pt").write_bytes(bytes([s, len(mods)]))
            result["model_sha256"] = model_digest(save_dir)
        return result
    return run


def test_a_repeated_run_resumes_from_its_kept_jobs_and_retrains_stale_ones(tmp_path, monkeypatch):
    import hapticframe_bench._perception as suite

    calls: list[tuple[int, str]] = []
    monkeypatch.setattr(suite, "_run_job", _fake_job(calls))
    model_dir, job_dir = tmp_path / "model", tmp_path / "jobs"
    jobs = [(s, mods, 1, {}, {}, str(model_dir)) for s in range(2)
            for mods in (("electrodes",), ALL)]
    lines: list[str] = []

    def run(fingerprint):
        calls.clear()
        lines.clear()
        return suite._map_jobs(jobs, 1, None, lines.append, job_dir, fingerprint)

    first = run("a" * 64)
    assert calls == [(0, "electrodes"), (0, ALL_KEY), (1, "electrodes"), (1, ALL_KEY)]
    assert sum(line.startswith("[") for line in lines) == 4
    # The same fingerprint: every job is kept, none trained, the results are the same.
    assert run("a" * 64) == first and calls == []
    assert lines[0].startswith("resuming: 4 of 4 jobs")
    # A job kept from other settings (its fingerprint differs) is trained again.
    stale_path = job_dir / "seed1-electrodes.json"
    stale = json.loads(stale_path.read_text())
    stale["fingerprint"] = "0" * 64
    stale_path.write_text(json.dumps(stale))
    assert run("a" * 64) == first and calls == [(1, "electrodes")]
    assert lines[0].startswith("resuming: 3 of 4 jobs")
    assert json.loads(stale_path.read_text())["fingerprint"] == "a" * 64
    # A half-written or foreign file is not a kept job either.
    stale_path.write_text("{not json")
    assert run("a" * 64) == first and calls == [(1, "electrodes")]
    # The job that saved the model reruns when the model is gone or changed.
    (model_dir / "weights.pt").unlink()
    assert run("a" * 64) == first and calls == [(0, ALL_KEY)]
    (model_dir / "weights.pt").write_bytes(b"other")
    assert run("a" * 64) == first and calls == [(0, ALL_KEY)]
    # Other settings: nothing is kept.
    run("b" * 64)
    assert len(calls) == 4


def test_figures_over_seeds_are_mean_and_sample_std():
    from hapticframe_bench._perception import _mean_std, _merge_seeds

    assert _mean_std([0.5, 0.7]) == pytest.approx({"mean": 0.6, "std": 0.1414213562, "n": 2})
    assert _mean_std([0.5]) == {"mean": 0.5, "std": 0.0, "n": 1}
    merged = _merge_seeds([{"a": {"x": 1.0, "y": None}, "b": 2.0},
                           {"a": {"x": 3.0, "y": None}, "b": 4.0}])
    assert merged["a"]["x"] == pytest.approx({"mean": 2.0, "std": 2 ** 0.5, "n": 2})
    assert merged["a"]["y"] is None and merged["b"]["mean"] == 3.0


def test_split_is_by_whole_trials_stratified_and_stage_inputs_have_thesis_sizes(tiny_run):
    flags = [True] * 10 + [False] * 20
    splits = split_cottonwood(flags, np.random.default_rng(0))
    for kind, n in ((True, 10), (False, 20)):
        got = [s for s, f in zip(splits, flags, strict=True) if f is kind]
        assert got.count("train") == round(0.6 * n) and got.count("validation") == round(0.2 * n)
    from hapticframe_bench._perception_data import TrialFeatures

    trial = TrialFeatures(0, "bbs", True, "train", np.zeros(4, dtype=np.int64),
                          {"pac": np.ones((4, 8, 22)), "pdc": np.ones((4, 5, 5)),
                           "electrodes": np.arange(4 * 19 * 5.0).reshape(4, 19, 5)})
    b = stage_inputs(trial, "b", ("pac", "pdc", "electrodes"))
    c = stage_inputs(trial, "c", ("pac", "pdc", "electrodes"))
    assert {m: v.shape[1] for m, v in b.items()} == {"pac": 8, "pdc": 5, "electrodes": 19}
    assert {m: v.shape[1] for m, v in c.items()} == {"pac": 176, "pdc": 25, "electrodes": 95}
    np.testing.assert_array_equal(b["electrodes"], trial.tensors["electrodes"][:, :, -1])
    with pytest.raises(ValueError, match="stage"):
        stage_inputs(trial, "e", ("pac",))


def test_bench_is_registered_and_plans_follow_the_options(tmp_path):
    registry = hapticframe.get_registry()
    assert "perception" in registry.benchmarks
    spec, _source = registry.benchmarks["perception"]
    assert spec.factory == "hapticframe_bench._perception:run_perception"
    quick = plan_for(BenchOptions(out_dir=tmp_path, quick=True))
    full = plan_for(BenchOptions(out_dir=tmp_path))
    assert quick.quick and not full.quick and full.cottonwood_trials == 750
    assert full.robustness_per_medium == 75
    assert plan_for(BenchOptions(out_dir=tmp_path, trials=4)).seeds == 4
    with pytest.raises(ValueError, match="seeds"):
        plan_for(BenchOptions(out_dir=tmp_path, trials=0))
    assert "train_device" not in full.rnn_settings  # cpu: the plan (and kept jobs) unchanged


def test_bench_device_is_checked_before_any_work(tmp_path, monkeypatch, capsys):
    import torch

    from hapticframe.cli._cli import main

    out = tmp_path / "never"
    assert main(["bench", "perception", "--quick", "--device", "gpu", "--out", str(out)]) == 2
    assert "--device 'gpu'" in capsys.readouterr().err
    if not torch.cuda.is_available():
        assert main(["bench", "perception", "--quick", "--device", "cuda", "--out", str(out)]) == 2
        assert "no CUDA device" in capsys.readouterr().err
    assert not (out / "jobs").exists()
    # Where torch sees a GPU, the device goes into the plan, so the report names it and a
    # job kept from a CPU run is not taken for a GPU one.
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    monkeypatch.setattr(torch.backends.cuda, "is_built", lambda: True)
    plan = plan_for(BenchOptions(out_dir=tmp_path, quick=True, device="cuda"))
    assert plan.rnn_settings["train_device"] == "cuda"
    assert plan.as_dict() != plan_for(BenchOptions(out_dir=tmp_path, quick=True)).as_dict()
    with pytest.raises(hapticframe.UsageError, match="1 CUDA device"):
        plan_for(BenchOptions(out_dir=tmp_path, quick=True, device="cuda:1"))


def _coded_trial(index, split, rng, n=60):
    from hapticframe_bench._perception_data import TrialFeatures

    labels = np.zeros(n, dtype=np.int64)
    if index % 2 == 0:
        labels[20:40] = 1
    tensors = {"pac": rng.standard_normal((n, 8, 22)), "pdc": rng.standard_normal((n, 5, 5)),
               "electrodes": rng.standard_normal((n, 19, 5))}
    codes = {m: rng.standard_normal((n, k)) * (rng.random((n, k)) < 0.3)
             for m, k in (("pac", 6), ("pdc", 4), ("electrodes", 5))}
    amplitudes = {m: 0.2 * rng.standard_normal((n, 2)) + labels[:, None] for m in codes}
    return TrialFeatures(index, "cottonwood_beads", index % 2 == 0, split, labels, tensors,
                         codes, amplitudes)


def test_amplitude_modalities_narrow_the_sfrnn_but_not_the_svm():
    from hapticframe_bench._perception_data import PerceptionData
    from hapticframe_bench._perception_models import Architecture, score, train_architecture

    rng = np.random.default_rng(3)
    splits = ["train"] * 6 + ["validation"] * 2 + ["test"] * 2
    data = PerceptionData([_coded_trial(i, s, rng) for i, s in enumerate(splits)], {}, 10)
    settings = {"max_epochs": 1, "window_frames": 20, "gru_layers": 1, "gru_units": 4,
                "fusion_units": 4, "batch_size": 16,
                "amplitude_modalities": ("pdc", "electrodes")}
    mods = ("pac", "pdc", "electrodes")
    sfrnn = train_architecture(data, Architecture("d", "rnn"), mods, 0, settings)
    assert sfrnn.amplitude_modalities == ("pdc", "electrodes")
    assert list(sfrnn.component.groups) == ["pac_code", "pdc_code", "pdc_amplitude",
                                            "electrodes_code", "electrodes_amplitude"]
    assert sfrnn.training_metrics["train_trials"] == 6
    assert sfrnn.training_metrics["validation_trials"] == 2
    _fractions(score(sfrnn, data.by_split("test"))["balanced_accuracy"])
    svm = train_architecture(data, Architecture("d", "svm"), mods, 0, settings,
                             {"calibration_folds": 2, "max_iter": 200})
    assert svm.amplitude_modalities is None
    assert svm.component.config.inputs == {"pac_d": 8, "pdc_d": 6, "electrodes_d": 7}
    _fractions(score(svm, data.by_split("test"))["balanced_accuracy"])
    every = train_architecture(data, Architecture("d", "rnn"), mods, 0,
                               {**settings, "amplitude_modalities": None})
    assert "pac_amplitude" in every.component.groups
    # The stage-(b) network reads no amplitude whatever the setting says.
    raw = train_architecture(data, Architecture("b", "rnn"), ("electrodes",), 0, settings)
    assert list(raw.component.groups) == ["electrodes_code"]
    assert raw.training_metrics["validation_source"] == "given"


def test_plans_keep_the_untared_vibration_amplitude_out_of_the_sfrnn(tmp_path):
    for quick in (True, False):
        plan = plan_for(BenchOptions(out_dir=tmp_path, quick=quick))
        assert plan.coder_settings["amplitude"] == "channel"
        assert tuple(plan.rnn_settings["amplitude_modalities"]) == ("pdc", "electrodes")


def test_job_fingerprint_follows_plan_seed_and_trials():
    from types import SimpleNamespace

    from hapticframe_bench._perception_data import TrialFeatures
    from hapticframe_bench._perception_jobs import job_fingerprint

    def data(labels):
        trial = TrialFeatures(0, "bbs", True, "train", np.asarray(labels, dtype=np.int64), {})
        return SimpleNamespace(trials=[trial])

    base = job_fingerprint(TINY, 1, data([0, 1, 1]))
    assert base == job_fingerprint(TINY, 1, data([0, 1, 1]))
    assert len(base) == 64
    changed_plan = SuitePlan(**{**TINY.__dict__, "max_epochs": 2})
    for other in (job_fingerprint(TINY, 2, data([0, 1, 1])),
                  job_fingerprint(changed_plan, 1, data([0, 1, 1])),
                  job_fingerprint(TINY, 1, data([0, 0, 1]))):
        assert other != base


def test_a_job_worker_runs_its_blas_pools_on_one_thread(monkeypatch):
    from threadpoolctl import threadpool_info

    import hapticframe_bench._perception as suite

    seen = {}

    def record(job):
        seen["threads"] = [pool["num_threads"] for pool in threadpool_info()]
        return {"job": job}

    monkeypatch.setattr(suite, "_run_job_single_thread", record)
    assert suite._run_job(("job",)) == {"job": ("job",)}
    assert seen["threads"] and all(n == 1 for n in seen["threads"])


def test_robustness_breakdown_groups_each_trial_by_its_conditions():
    from hapticframe_bench._perception_data import TrialFeatures
    from hapticframe_bench._perception_models import robustness_breakdown

    def trial(i, medium, pose, offset, labels):
        return TrialFeatures(index=i, medium=medium, has_object=True, split="robustness",
                             labels=np.asarray(labels), tensors={}, orientation_deg=pose,
                             object_offset_m=offset)

    trials = [trial(0, "bbs", 0.0, 0.0, [0, 1, 1, 0]), trial(1, "bbs", 20.0, 0.035, [0, 1, 1, 0]),
              trial(2, "poppy_seed", 20.0, 0.0, [0, 0, 1, 1])]
    # Read at once at 0°; missed at 20° in BBs; read one frame late in poppy seed.
    predicted = [np.array([0, 1, 1, 0]), np.zeros(4, int), np.array([0, 0, 0, 1])]
    out = robustness_breakdown(trials, predicted)
    assert list(out["orientation_deg"]) == ["0", "20"]
    assert list(out["object_offset_m"]) == ["0", "0.035"]
    upright, tilted = out["orientation_deg"]["0"], out["orientation_deg"]["20"]
    assert upright["contact_recall"] == 1.0 and upright["onset_delay_frames"] == 0.0
    assert tilted["trials"] == 2 and tilted["missed_contacts"] == 1
    assert tilted["contact_recall"] == 0.25 and tilted["onset_delay_frames"] == 1.0
    assert out["object_offset_m"]["0"]["trials"] == 2
    assert set(out["medium_orientation_deg"]) == {"bbs", "poppy_seed"}
    assert list(out["medium_orientation_deg"]["poppy_seed"]) == ["20"]
    assert out["medium_orientation_deg"]["bbs"]["20"]["missed_contacts"] == 1
    with pytest.raises(ValueError):
        robustness_breakdown(trials, predicted[:2])


def test_accuracy_axes_start_just_below_the_lowest_value():
    from hapticframe_bench._perception_report import accuracy_axis_range

    assert accuracy_axis_range([91.0, 99.5, float("nan")]) == (85.0, 101.0)
    assert accuracy_axis_range([80.8, 97.0]) == (75.0, 101.0)
    assert accuracy_axis_range([1.0, 50.0]) == (0.0, 101.0)
    assert accuracy_axis_range([float("nan")]) == (0.0, 101.0)
