"""The registration records of sf-rnn, fusion-rnn and linear-svm.

The conformance kit runs on them in ``tests/test_bundled_conformance.py``.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

import hapticframe
from hapticframe import Kind

pytest.importorskip("torch")
pytest.importorskip("sklearn")

NAMES = ["sf-rnn", "fusion-rnn", "linear-svm"]
CODES = {"pac_code": (200,), "pdc_code": (100,), "electrodes_code": (100,)}


@pytest.fixture(scope="module")
def registry() -> hapticframe.Registry:
    return hapticframe.make_plugin_manager(modules=["hapticframe_sfrnn.plugin"]).registry


def test_specs_consume_what_the_default_configs_read(registry: hapticframe.Registry) -> None:
    from hapticframe_sfrnn._config import FusionRNNConfig, LinearSVMConfig, SFRNNConfig

    plugins = registry.plugins[Kind.CLASSIFIER]
    for name in NAMES:
        spec = plugins[name].spec
        assert {k: v.kit_shape for k, v in spec.consumes.items()} == CODES
        assert "hapticframe[learn]" in spec.install_hint
    assert plugins["sf-rnn"].spec.requires == ("torch",)
    assert plugins["linear-svm"].spec.requires == ("sklearn",)
    sf = SFRNNConfig()
    assert (sf.gru_layers, sf.gru_units, sf.dropout, sf.window_frames) == (4, 50, 0.4, 50)
    assert (sf.free_stride_frames, sf.contact_stride_frames) == (10, 5)
    assert {f"{m}_code": (sf.code_size(m),) for m in sf.modalities} == CODES
    assert {f"{m}_code": (FusionRNNConfig().code_size(m),) for m in sf.modalities} == CODES
    assert {k: (v,) for k, v in LinearSVMConfig().inputs.items()} == CODES


def test_package_import_is_light() -> None:
    code = (
        "import sys, hapticframe_sfrnn, hapticframe_sfrnn.plugin\n"
        "print(sorted(m for m in ('torch', 'sklearn') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_config_rejects_bad_values() -> None:
    from pydantic import ValidationError

    from hapticframe_sfrnn._config import LinearSVMConfig, SFRNNConfig

    with pytest.raises(ValidationError):
        SFRNNConfig(modalities=())
    with pytest.raises(ValidationError):
        SFRNNConfig(modalities=("pac", "pac"))
    with pytest.raises(ValidationError):
        SFRNNConfig(dropout=1.0)
    with pytest.raises(ValidationError):
        LinearSVMConfig(inputs={})
    with pytest.raises(ValidationError):
        LinearSVMConfig(inputs={"pac": 0})
    assert SFRNNConfig(modalities=("electrodes", "pac")).modalities == ("pac", "electrodes")
