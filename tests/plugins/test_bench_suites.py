"""The ``bhm`` and ``latency`` suites, the targets every suite reports, the separability
study of the synthetic BioTac data, and the list of suites (``hapticframe bench``)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import hapticframe
from hapticframe import BenchOptions
from hapticframe_bench import (
    Target,
    benchmark_bhm,
    check_targets,
    linear_svm_separability,
    measure_chain_latency,
    run_bhm_bench,
    synthetic_biotac_frames,
)
from hapticframe_bench._targets import targets_markdown

# --- targets and verdicts ------------------------------------------------------------------------


def test_each_target_gets_its_measurement_and_a_verdict():
    targets = (Target("fit_ms", "fit 3,000 points", 25.0, "ms"),
               Target("update_ms", "update 200 points", 2.0, "ms"),
               Target("ahead", "media ahead", 5.0, digits=0, at_most=False),
               Target("missing_ms", "never measured", 1.0, "ms"))
    checks = check_targets(targets, {"fit_ms": 16.74, "update_ms": 2.5, "ahead": 5,
                                     "missing_ms": float("nan")})
    assert [c.verdict for c in checks] == ["met", "missed", "met", "not measured"]
    assert checks[0].line() == "fit 3,000 points: 16.7 ms  (target <= 25.0 ms)  met"
    assert checks[1].line() == "update 200 points: 2.5 ms  (target <= 2.0 ms)  missed"
    assert checks[2].line() == "media ahead: 5  (target >= 5)  met"
    assert checks[3].line().endswith("not measured") and checks[3].as_dict()["met"] is None
    assert checks[1].as_dict() == {"label": "update 200 points", "value": 2.5, "limit": 2.0,
                                   "unit": "ms", "comparison": "<=", "met": False}
    table = targets_markdown(checks)
    assert table[2] == "| fit 3,000 points | 16.7 ms | ≤ 25.0 ms | met |"
    assert len(table) == 2 + len(targets)


# --- bhm -----------------------------------------------------------------------------------------


def test_bhm_benchmark_reports_its_figures() -> None:
    result = benchmark_bhm(rng_seed=0, repeats=1)
    for key in ("fit_3000_ms", "update_200_ms", "grid_15000_mean_std_ms", "rds_fit_3000_ms"):
        assert result[key] > 0
    assert result["grid_points"] == 15000
    assert result["auc"] >= 0.99 and result["rds_auc"] >= 0.99


def test_bhm_suite_prints_and_writes_each_target_with_its_verdict(tmp_path, monkeypatch):
    import hapticframe_bench._bhm as suite

    # The timings are the bench's business; here a fixed result shows what is written.
    figures = {"fit_3000_ms": 16.7, "update_200_ms": 2.4, "grid_15000_mean_std_ms": 2.0}
    fake = {"blas_threads": "1 (threadpoolctl)", "auc": 0.997, "rds_auc": 0.996,
            "targets_ms": {"fit_3000": 25.0, "update_200": 2.0, "grid_15000_mean_std": 40.0}}
    for key, value in figures.items():
        fake |= {key: value, key.replace("_ms", "_min_ms"): value, "rds_" + key: 2 * value}
    seen = {}

    def benchmark(rng_seed, repeats):
        seen["repeats"] = repeats
        return dict(fake)

    monkeypatch.setattr(suite, "benchmark_bhm", benchmark)
    # The GP rows are measured for real elsewhere (test_gp_occupancy_bench.py).
    monkeypatch.setattr(suite, "benchmark_gp_scaling", lambda **kw: {
        "rows": [], "crossover": {}, "sizes": [], "exact_max": 0})
    lines: list[str] = []
    result = run_bhm_bench(BenchOptions(out_dir=tmp_path, quick=True, echo=lines.append))
    assert seen["repeats"] == 5
    assert "fit 3,000 labelled points: 16.7 ms  (target <= 25.0 ms)  met" in lines
    assert "add 200 points to that map: 2.4 ms  (target <= 2.0 ms)  missed" in lines
    written = json.loads((tmp_path / "bhm.json").read_text())
    assert written["targets"]["update_200_ms"]["met"] is False
    assert written["targets"]["fit_3000_ms"] == {
        "label": "fit 3,000 labelled points", "value": 16.7, "limit": 25.0, "unit": "ms",
        "comparison": "<=", "met": True}
    assert written["targets_met"] is False and result["targets_met"] is False
    md = (tmp_path / "bhm.md").read_text()
    assert "| add 200 points to that map | ≤ 2 ms | 2.4 ms | 2.4 ms | missed | 4.8 ms |" in md
    assert "load average" in md


# --- latency -------------------------------------------------------------------------------------


def test_both_latency_suites_time_frames_with_one_thread_and_a_fresh_stream_per_trial() -> None:
    # bench latency and bench perception share one timing loop: the classifier is reset at
    # each recording, torch runs on one thread, and timing stops after n_frames in all.
    torch = pytest.importorskip("torch")
    from hapticframe.kinds import SampleBatch
    from hapticframe_bench._latency import _time_frames

    class Stage:
        def __init__(self) -> None:
            self.resets = 0
            self.threads: list[int] = []

        def reset(self) -> None:
            self.resets += 1

        def update(self, batch: object) -> object:
            self.threads.append(torch.get_num_threads())
            return batch

    recordings = [SampleBatch(np.arange(n) / 100.0, {"x": np.zeros(n)}) for n in (3, 4, 5)]
    extractor, coder, classifier = Stage(), Stage(), Stage()
    original = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        times = _time_frames(recordings, extractor, coder, classifier, 9)
        assert torch.get_num_threads() == 2  # restored afterwards
    finally:
        torch.set_num_threads(original)
    assert extractor.resets == classifier.resets == 3  # one fresh stream per recording
    assert classifier.threads == [1] * 9  # 3 + 4 + the first 2 of the last
    assert {k: v.size for k, v in times.items()} == dict.fromkeys(
        ("emd", "coding", "classify", "total", "cpu"), 9
    )
    assert np.all(times["total"] >= times["emd"])


def test_latency_probe_reports_its_figures() -> None:
    from hapticframe_tactile_features import EMDFeaturesConfig, SparseCodingConfig

    # Not a speed test: the figures only have to exist and be consistent.
    report = measure_chain_latency(40, fit_frames=0)
    assert report["frames"] == 40 and report["threads"] == 1
    assert 0 < report["latency_ms_median"] <= report["latency_ms_p99"] <= report["latency_ms_max"]
    assert report["emd_ms_median"] > 0 and report["coding_ms_median"] >= 0
    assert 0 < report["cpu_ms_median"] <= report["cpu_ms_p99"]
    assert report["emd_ms_median"] <= report["emd_ms_p99"]
    assert report["coding_ms_median"] <= report["coding_ms_p99"]
    assert report["emd_backend"] in {"numba", "numpy"}
    assert report["encoder"] in {"numba", "sklearn"}
    assert "classify_ms_median" not in report
    reference = measure_chain_latency(
        20,
        fit_frames=0,
        emd_config=EMDFeaturesConfig(emd_backend="numpy"),
        coding_config=SparseCodingConfig(encoder="sklearn"),
    )
    assert (reference["emd_backend"], reference["encoder"]) == ("numpy", "sklearn")


def test_backend_names_resolve_as_the_components_do() -> None:
    from hapticframe_tactile_features import emd_backend_in_use, encoder_in_use

    assert emd_backend_in_use("numpy") == "numpy" and encoder_in_use("sklearn") == "sklearn"
    assert emd_backend_in_use() in {"numba", "numpy"} and encoder_in_use() in {"numba", "sklearn"}
    with pytest.raises(ValueError, match="backend"):
        emd_backend_in_use("fortran")
    with pytest.raises(ValueError, match="backend"):
        encoder_in_use("fortran")


def test_pyemd_comparison_reports_both_pairings() -> None:
    pytest.importorskip("PyEMD")
    from hapticframe_bench import compare_emd_with_pyemd

    report = compare_emd_with_pyemd(100, repeats=1)
    assert report["samples"] == 100
    for key in ("emd_ms_default", "pyemd_ms_default", "emd_ms_fixed10", "pyemd_ms_fixed10"):
        assert report[key] > 0


def test_step_latency_probe_reports_its_figures() -> None:
    pytest.importorskip("torch")
    from hapticframe.kinds import BuildContext
    from hapticframe_bench import measure_step_latency
    from hapticframe_sfrnn import SFRNNClassifier, SFRNNConfig

    # Not a speed test: the figures only have to exist and be consistent.
    context = BuildContext("clf", np.random.default_rng(0))
    clf = SFRNNClassifier(SFRNNConfig(progress=False), context)
    report = measure_step_latency(clf, frames=50)
    assert report["frames"] == 50
    assert 0 < report["latency_ms_median"] <= report["latency_ms_p99"] <= report["latency_ms_max"]


def test_latency_probe_pools_its_passes_and_lists_each() -> None:
    report = measure_chain_latency(15, fit_frames=0, passes=3)
    assert report["frames"] == 45 and report["passes"] == 3
    assert len(report["pass_medians_ms"]) == len(report["pass_p99s_ms"]) == 3
    assert all(0 < m <= p for m, p in zip(report["pass_medians_ms"], report["pass_p99s_ms"],
                                          strict=True))
    assert min(report["pass_medians_ms"]) <= report["latency_ms_p99"]
    with pytest.raises(ValueError, match="passes"):
        measure_chain_latency(5, fit_frames=0, passes=0)


def test_torch_step_probe_times_the_network_and_a_plain_gru() -> None:
    pytest.importorskip("torch")
    from hapticframe.kinds import BuildContext
    from hapticframe_bench import measure_torch_steps
    from hapticframe_sfrnn import SFRNNClassifier, SFRNNConfig

    # Not a speed test: the figures only have to exist and be consistent.
    clf = SFRNNClassifier(SFRNNConfig(progress=False, gru_layers=2, gru_units=8),
                          BuildContext("clf", np.random.default_rng(0)))
    report = measure_torch_steps(clf, frames=20)
    assert set(report) == {"network_ms_median", "network_ms_p99", "gru_ms_median", "gru_ms_p99"}
    assert 0 < report["network_ms_median"] <= report["network_ms_p99"]
    assert 0 < report["gru_ms_median"] <= report["gru_ms_p99"]


def test_latency_suite_times_the_whole_chain_and_reports_its_targets(tmp_path, monkeypatch):
    pytest.importorskip("torch")
    pytest.importorskip("sklearn")
    import hapticframe_bench._latency as suite

    monkeypatch.setattr(suite, "compare_emd_with_pyemd",
                        lambda repeats, seed: {"samples": 2200, "emd_ms_default": 1.0,
                                               "pyemd_ms_default": 100.0, "speedup_default": 100.0,
                                               "emd_ms_fixed10": 2.0, "pyemd_ms_fixed10": 50.0,
                                               "speedup_fixed10": 25.0})
    lines: list[str] = []
    result = suite.run_latency_bench(BenchOptions(out_dir=tmp_path, trials=30, quick=True,
                                                  echo=lines.append))
    chain = result["chain"]
    assert chain["frames"] == 30 and chain["classify_ms_median"] > 0
    assert chain["emd_ms_median"] + chain["classify_ms_median"] <= chain["latency_ms_p99"] * 2
    written = json.loads((tmp_path / "latency.json").read_text())
    assert set(written["targets"]) == {"latency_ms_median", "latency_ms_p99"}
    for record in written["targets"].values():
        verdict = "met" if record["met"] else "missed"
        assert any(line.startswith(record["label"]) and line.endswith(verdict) for line in lines)
    assert written["targets"]["latency_ms_median"]["limit"] == 1.0
    assert written["targets"]["latency_ms_p99"]["limit"] == 2.0
    assert written["torch_steps"]["gru_ms_median"] > 0
    assert chain["passes"] == 1 and len(chain["pass_medians_ms"]) == 1
    md = (tmp_path / "latency.md").read_text()
    assert "| chain per frame, median |" in md and "(100x)" in md
    assert "plain torch GRU" in md and "load average" in md


# --- separability of the synthetic BioTac frames -------------------------------------------------


def test_linear_svm_on_raw_frames_is_not_trivially_separable() -> None:
    pytest.importorskip("sklearn")
    from hapticframe_biotac import frame_features, generate_trial, training_specs

    specs = training_specs(np.random.default_rng(12))[:90]
    rng = np.random.default_rng(13)
    trials = [generate_trial(spec, rng) for spec in specs]
    assert frame_features(trials[0]).shape == (trials[0].n_frames, 44)
    report = linear_svm_separability(trials, np.random.default_rng(14))
    assert report["accuracy"] <= 0.90
    assert report["balanced_accuracy"] <= 0.90
    assert report["balanced_accuracy"] >= 0.60  # yet the contact is there to be learnt
    assert report["n_test_trials"] + report["n_train_trials"] == 90
    with pytest.raises(ValueError, match="test_fraction"):
        linear_svm_separability(trials, rng, test_fraction=1.0)


# --- the suites and their list -------------------------------------------------------------------


def test_every_suite_is_registered_by_hapticframe_bench():
    registry = hapticframe.get_registry()
    assert {"search", "perception", "bhm", "latency"} <= set(registry.benchmarks)
    for name in ("search", "perception", "bhm", "latency"):
        spec, _source = registry.benchmarks[name]
        assert spec.factory.startswith("hapticframe_bench."), spec.factory
        module, attribute = spec.factory.split(":")
        assert callable(getattr(__import__(module, fromlist=[attribute]), attribute))


def test_bench_without_a_name_lists_the_suites_one_line_each(capsys):
    from hapticframe.cli._cli import main

    assert main(["bench"]) == 0
    lines = capsys.readouterr().out.splitlines()
    registry = hapticframe.get_registry()
    assert len(lines) == len(registry.benchmarks)
    for line, name in zip(lines, sorted(registry.benchmarks), strict=True):
        assert line.split()[0] == name
        assert registry.benchmarks[name][0].summary in line


def test_synthetic_biotac_frames_have_the_sensor_layout():
    frames = synthetic_biotac_frames(5, np.random.default_rng(0))
    assert {k: v.shape for k, v in frames.channels.items()} == {
        "pac": (5, 22), "pdc": (5,), "electrodes": (5, 19)}
    np.testing.assert_allclose(np.diff(frames.timestamps_s), 0.01)
