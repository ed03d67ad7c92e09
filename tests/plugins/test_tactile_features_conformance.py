"""The conformance kit on emd-features and sparse-coding, the chain, and the latency probe."""

from __future__ import annotations

import numpy as np
import pytest
from hapticframe_tactile_features._config import EMDFeaturesConfig, SparseCodingConfig
from hapticframe_tactile_features._emd_features import EMDFeatureExtractor
from hapticframe_tactile_features._latency import measure_chain_latency, synthetic_biotac_frames
from hapticframe_tactile_features._sparse_coding import SparseCodingExtractor

import hapticframe
from hapticframe import Kind
from hapticframe.kinds import BuildContext
from hapticframe.testing import run_checks

pytest.importorskip("sklearn")


@pytest.fixture(scope="module")
def registry() -> hapticframe.Registry:
    manager = hapticframe.make_plugin_manager(modules=["hapticframe_tactile_features.plugin"])
    return manager.registry


@pytest.mark.parametrize("name", ["emd-features", "sparse-coding"])
def test_conformance_kit_passes(registry: hapticframe.Registry, name: str) -> None:
    spec = registry.plugins[Kind.FEATURE_EXTRACTOR][name].spec
    results = run_checks(spec, registry=registry)
    failed = [f"{r.check}: {r.message}" for r in results if r.status != "PASS"]
    assert not failed, failed
    names = {r.check for r in results}
    assert {
        "check_numerical_extremes",
        "check_streaming_matches_batch",
        "check_lazy_import",
    } <= names


def test_specs_declare_what_the_default_configs_consume(registry: hapticframe.Registry) -> None:
    plugins = registry.plugins[Kind.FEATURE_EXTRACTOR]
    emd_spec, code_spec = plugins["emd-features"].spec, plugins["sparse-coding"].spec
    assert emd_spec.consumes == {"pac": (22,), "pdc": (), "electrodes": (19,)}
    assert code_spec.consumes == {
        "pac_imfs": (8, 22),
        "pdc_imfs": (5, 5),
        "electrodes_window": (19, 5),
    }
    assert code_spec.requires == ("sklearn",) and "hapticframe[learn]" in code_spec.install_hint
    # What emd-features emits is exactly what sparse-coding consumes.
    fx = EMDFeatureExtractor(EMDFeaturesConfig(), BuildContext("fx", np.random.default_rng(0)))
    assert {k: v.shape for k, v in fx.output_channels.items()} == code_spec.consumes


def test_chain_from_biotac_frames_to_codes() -> None:
    frames = synthetic_biotac_frames(30, np.random.default_rng(0))
    fx = EMDFeatureExtractor(
        EMDFeaturesConfig(delay_frames=2), BuildContext("fx", np.random.default_rng(0))
    )
    coder = SparseCodingExtractor(
        SparseCodingConfig(), BuildContext("codes", np.random.default_rng(1))
    )
    codes = coder.update(fx.update(frames))
    assert {k: v.shape for k, v in codes.channels.items()} == {
        "pac_code": (28, 200),
        "pdc_code": (28, 100),
        "electrodes_code": (28, 100),
    }
    assert np.array_equal(codes.timestamps_s, frames.timestamps_s[:-2])
    assert all(np.isfinite(v).all() and np.count_nonzero(v) > 0 for v in codes.channels.values())


def test_latency_probe_reports_its_figures() -> None:
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
    reference = measure_chain_latency(
        20,
        fit_frames=0,
        emd_config=EMDFeaturesConfig(emd_backend="numpy"),
        coding_config=SparseCodingConfig(encoder="sklearn"),
    )
    assert (reference["emd_backend"], reference["encoder"]) == ("numpy", "sklearn")


def test_pyemd_comparison_reports_both_pairings() -> None:
    pytest.importorskip("PyEMD")
    from hapticframe_tactile_features._latency import compare_emd_with_pyemd

    report = compare_emd_with_pyemd(100, repeats=1)  # the figures' size is the benchmark's
    assert report["samples"] == 100
    for key in ("emd_ms_default", "pyemd_ms_default", "emd_ms_fixed10", "pyemd_ms_fixed10"):
        assert report[key] > 0
