"""The EMD fidelity suite (``hapticframe bench emd-fidelity``, issue 18 §4): its measures,
its reference and cross-check, its choice rule and its registration. Not a speed test."""

from __future__ import annotations

import numpy as np
import pytest

import hapticframe
from hapticframe_bench._emd_fidelity import (
    WINDOWS,
    Setting,
    choose_default,
    fidelity_table,
    imf_correlations,
    orthogonality_index,
    pyemd_reference,
    signal_windows,
)
from hapticframe_tactile_features import EMDFeaturesConfig, emd


def _two_tones(n: int) -> np.ndarray:
    t = np.arange(n) / n
    return np.sin(2 * np.pi * 32 * t) + 0.5 * np.sin(2 * np.pi * 5 * t)


def test_orthogonality_index_is_zero_for_orthogonal_parts_and_grows_with_leakage() -> None:
    t = np.arange(1000) / 1000
    fast, slow = np.sin(2 * np.pi * 50 * t), np.sin(2 * np.pi * 3 * t)
    # Whole periods: the two tones are orthogonal to rounding.
    assert abs(orthogonality_index(np.vstack([fast, slow]), np.zeros(1000))) < 1e-12
    # Half of the slow tone leaked into the fast row: IO = 2<0.5 s, 0.5 s> / <s + f, s + f>.
    leaky = np.vstack([fast + 0.5 * slow, 0.5 * slow])
    assert orthogonality_index(leaky, np.zeros(1000)) == pytest.approx(0.25 / 1.0, rel=1e-9)
    # The residue counts as a component, centred; zero rows add nothing.
    padded = np.vstack([fast, np.zeros(1000)])
    assert abs(orthogonality_index(padded, slow + 7.0)) < 1e-12
    assert orthogonality_index(np.zeros((2, 8)), np.zeros(8)) == 0.0


def test_imf_correlations_score_missing_modes_zero_and_ignore_scale() -> None:
    rng = np.random.default_rng(0)
    reference = rng.standard_normal((4, 200))
    same = 3.0 * reference + 1.0
    assert imf_correlations(same, reference) == pytest.approx([1.0, 1.0, 1.0])
    missing = same.copy()
    missing[2] = 0.0
    assert imf_correlations(missing, reference)[2] == 0.0
    assert imf_correlations(-reference, reference) == pytest.approx([-1.0, -1.0, -1.0])
    assert imf_correlations(reference[:1], reference).tolist()[1:] == [0.0, 0.0]


def test_windows_come_from_the_synthetic_biotac_and_repeat_with_the_seed() -> None:
    for kind, (_, samples, _) in WINDOWS.items():
        first = signal_windows(kind, 2, seed=3)
        assert [w.shape for w in first] == [(samples,)] * 2
        assert all(np.isfinite(w).all() and np.ptp(w) > 0 for w in first)
        again = signal_windows(kind, 2, seed=3)
        assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert not np.array_equal(signal_windows("pdc-64", 1, 3)[0], signal_windows("pdc-64", 1, 4)[0])


def test_reference_agrees_with_pyemd_under_the_same_rule() -> None:
    pytest.importorskip("PyEMD")
    # Two tones: well-separated modes, so the converged IMFs are unique and the libraries'
    # spline ends are the only difference (the suite checks broadband pac windows too).
    # A rule a little looser than REFERENCE's keeps PyEMD's part under a second.
    rule = Setting(1e-5, 500)
    x = _two_tones(256)
    ours = emd(x, 4, sd_threshold=rule.sd_threshold, max_sifts=rule.max_sifts,
               residue_ratio=0.0)
    assert ours.sift_counts.max() > 10  # converged, not stopped after a sift or two
    theirs = pyemd_reference(x, 4, rule)
    assert theirs is not None and theirs.shape == (4, 256)
    corr = imf_correlations(theirs, ours.imfs, 2)
    assert corr.min() > 0.999


def test_looser_sifting_agrees_less_with_the_reference_on_biotac_pac() -> None:
    windows = {"pac-512": signal_windows("pac-512", 2, seed=0)}
    table = fidelity_table(windows, [Setting(0.3, 50), Setting(0.0, 1), Setting(1e-3, 50)],
                           repeats=1, cross_check=False)
    rows = {r["label"]: r for r in table["rows"]}
    loose, one, strict = rows["SD 0.3, cap 50"], rows["fixed 1"], rows["SD 0.001, cap 50"]
    assert one["sifts_per_imf"] == 1.0
    assert strict["sifts_per_imf"] > loose["sifts_per_imf"]
    # IMF 1 (the pac detail) moves towards the reference as sifting tightens.
    assert strict["correlation_imf"][0] > loose["correlation_imf"][0]
    assert strict["correlation_imf"][0] > one["correlation_imf"][0]
    for r in table["rows"]:
        assert -1.0 <= r["correlation_min"] <= r["correlation_mean"] <= 1.0
        assert r["ms_per_window"] > 0 and np.isfinite(r["orthogonality"])
    ref = table["reference"]["kinds"]["pac-512"]
    assert ref["sifts_per_imf"] > strict["sifts_per_imf"]
    assert len(ref["stability_correlation"]) == 3


def test_choice_is_the_cheapest_candidate_within_tolerance_of_the_best() -> None:
    downstream = [
        {"sd_threshold": 0.3, "max_sifts": 50, "label": "a", "test": 0.90, "robustness": 0.80},
        {"sd_threshold": 0.1, "max_sifts": 50, "label": "b", "test": 0.95, "robustness": 0.85},
        {"sd_threshold": 0.01, "max_sifts": 50, "label": "c", "test": 0.955, "robustness": 0.855},
        {"sd_threshold": 0.0, "max_sifts": 10, "label": "d", "test": 0.96, "robustness": 0.84},
    ]
    frame = {"a": {"frame_ms_median": 0.1}, "b": {"frame_ms_median": 0.3},
             "c": {"frame_ms_median": 0.4}, "d": {"frame_ms_median": 0.2}}
    # "a" is cheapest but 6 points worse; "d" is cheap but 1.5 points short on robustness.
    assert choose_default(downstream, frame) == Setting(0.1, 50)
    assert choose_default(downstream, frame, tolerance=0.1) == Setting(0.3, 50)
    with pytest.raises(ValueError, match="downstream"):
        choose_default([], frame)


def test_choice_when_no_candidate_is_near_the_best_on_both_sets() -> None:
    # One setting is best on the test split, another on the robustness set, each more than
    # the tolerance behind on the other (as `bench emd-fidelity --quick` measured): the one
    # whose larger shortfall is the smallest wins, not an error.
    downstream = [
        {"sd_threshold": 0.0, "max_sifts": 10, "label": "fixed", "test": 0.613,
         "robustness": 0.521},
        {"sd_threshold": 0.01, "max_sifts": 50, "label": "sd", "test": 0.530,
         "robustness": 0.534},
    ]
    frame = {"fixed": {"frame_ms_median": 0.3}, "sd": {"frame_ms_median": 0.2}}
    assert choose_default(downstream, frame) == Setting(0.0, 10)


def test_emd_features_default_is_the_measured_choice() -> None:
    # docs/benchmarks.md "EMD: sifting against fidelity" chose this setting from the table;
    # change both together.
    config = EMDFeaturesConfig()
    assert (config.sd_threshold, config.max_sifts) == (0.01, 50)


def test_suite_is_registered() -> None:
    registry = hapticframe.get_registry()
    spec, _source = registry.benchmarks["emd-fidelity"]
    assert spec.factory == "hapticframe_bench._emd_fidelity:run_emd_fidelity"


def test_suite_writes_its_table_and_choice(tmp_path, monkeypatch) -> None:
    import json
    import sys

    import hapticframe_bench._emd_fidelity as suite
    from hapticframe import BenchOptions

    # Two settings, one window per kind, a stand-in for the downstream training (minutes)
    # and no PyEMD (its import alone takes seconds): what is left is the suite's own path.
    monkeypatch.setattr(suite, "SETTINGS", (Setting(0.1, 10), Setting(0.0, 2)))
    monkeypatch.setitem(sys.modules, "PyEMD", None)
    seen: list[list[str]] = []

    def fake_downstream(settings, **_kwargs):
        seen.append([s.label for s in settings])
        return [{**s.as_dict(), "label": s.label, "modalities": ["pdc"], "emd_s": 1.0,
                 "test": 0.7 + 0.01 * i, "robustness": 0.6, "rnn_test_seeds": [0.7],
                 "rnn_robustness_seeds": [0.6], "svm_test": 0.5, "svm_robustness": 0.5}
                for i, s in enumerate(settings)]

    monkeypatch.setattr(suite, "downstream_accuracy", fake_downstream)
    lines: list[str] = []
    result = suite.run_emd_fidelity(BenchOptions(out_dir=tmp_path, trials=1, quick=True,
                                                 echo=lines.append))
    written = json.loads((tmp_path / "emd-fidelity.json").read_text())
    assert len(written["fidelity"]["rows"]) == 2 * len(WINDOWS)
    assert written["fidelity"]["reference"]["kinds"]["pac-512"]["pyemd_correlation"] is None
    default = EMDFeaturesConfig()
    assert written["current_default"]["sd_threshold"] == default.sd_threshold
    # Quick scores two candidates, the current default last; the better one is chosen.
    assert seen[0][-1] == Setting(default.sd_threshold, default.max_sifts).label
    assert result["chosen"]["label"] == seen[0][-1]
    assert result["large"] is None and any("PyEMD" in line for line in lines)
    markdown = (tmp_path / "emd-fidelity.md").read_text()
    assert f"Chosen: {seen[0][-1]}." in markdown and "| fixed 2 |" in markdown
