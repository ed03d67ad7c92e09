"""The specs of emd-features and sparse-coding, and the chain from BioTac frames to codes.

The conformance kit runs on these two components with the other bundled plugins, in
tests/test_bundled_conformance.py.
"""

from __future__ import annotations

import numpy as np
import pytest

import hapticframe
from hapticframe import Kind
from hapticframe.kinds import BuildContext
from hapticframe_bench import synthetic_biotac_frames
from hapticframe_tactile_features import (
    EMDFeatureExtractor,
    EMDFeaturesConfig,
    SparseCodingConfig,
    SparseCodingExtractor,
)

pytest.importorskip("sklearn")


@pytest.fixture(scope="module")
def registry() -> hapticframe.Registry:
    manager = hapticframe.make_plugin_manager(modules=["hapticframe_tactile_features.plugin"])
    return manager.registry


def test_specs_declare_what_the_default_configs_consume(registry: hapticframe.Registry) -> None:
    plugins = registry.plugins[Kind.FEATURE_EXTRACTOR]
    emd_spec, code_spec = plugins["emd-features"].spec, plugins["sparse-coding"].spec
    emd_reads = {k: v.kit_shape for k, v in emd_spec.consumes.items()}
    assert emd_reads == {"pac": (22,), "pdc": (), "electrodes": (19,)}
    assert {k: v.kit_shape for k, v in code_spec.consumes.items()} == {
        "pac_imfs": (8, 22),
        "pdc_imfs": (5, 5),
        "electrodes_window": (19, 5),
    }
    assert code_spec.requires == ("sklearn",) and "hapticframe[learn]" in code_spec.install_hint
    # What emd-features emits is exactly what sparse-coding consumes.
    fx = EMDFeatureExtractor(EMDFeaturesConfig(), BuildContext("fx", np.random.default_rng(0)))
    code_reads = {k: v.kit_shape for k, v in code_spec.consumes.items()}
    assert {k: v.shape for k, v in fx.output_channels.items()} == code_reads


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
