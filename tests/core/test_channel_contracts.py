"""Channels as contracts (issue 34 §2): a consumer declares what it reads, ``validate``
refuses wiring whose producer disagrees (at the consumer's ``inputs:`` line, both
declarations shown), a run refuses the same against what a built producer reports, and
``hapticframe plugins --channels`` lists both sides."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import pytest

from hapticframe import ChannelSpec, ClassifierSpec, PluginConfig, get_registry
from hapticframe._contracts import channel_disagreement
from hapticframe.cli._cli import main

SUPPORT = Path(__file__).resolve().parent.parent / "support"
PLUGIN = ("--plugin-module", "lab_newcomer")

WIRING = """\
schema_version: 1
name: contracts
seed: 1
sensors:
  - id: lab
    type: {sensor}
    config: {{samples_per_read: 1}}
classifiers:
  - id: planar
    type: lab-planar
    inputs: [lab]
run: {{duration_s: 0.5, figures: false}}
"""


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(SUPPORT / "lab_newcomer.py", tmp_path / "lab_newcomer.py")
    monkeypatch.delitem(sys.modules, "lab_newcomer", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_validate_refuses_a_3_axis_force_into_a_planar_consumer_at_its_inputs_line(
    lab_dir, capsys
):
    path = lab_dir / "wiring.yaml"
    path.write_text(WIRING.format(sensor="lab-fake-ft-clocked"))
    assert main(["validate", *PLUGIN, str(path)]) == 2
    err = capsys.readouterr().err
    assert "wiring.yaml:11: classifiers[0].inputs" in err  # the `inputs: [lab]` line
    assert "reads force_n (2,) N: uses the x component" in err
    assert "declares force_n (3,) N: x, y, z in the sensor frame" in err
    assert "shape (3,) is not (2,)" in err


def test_a_run_refuses_the_same_when_only_the_built_sensor_says_its_channels(lab_dir, capsys):
    # The newcomer's sensor declares nothing in its spec: validate cannot know; the run
    # holds what the built sensor reports to the contract before anything runs.
    path = lab_dir / "wiring.yaml"
    path.write_text(WIRING.format(sensor="lab-fake-ft"))
    assert main(["validate", *PLUGIN, str(path)]) == 0
    out = lab_dir / "out"
    assert main(["run", *PLUGIN, str(path), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "classifiers[0].inputs" in err and "delivers (as built) force_n (3,) N" in err
    assert not (out / "trace.npz").exists()


def test_shapes_with_any_size_and_units_are_compared():
    force = ChannelSpec((None,), "N")
    assert channel_disagreement(ChannelSpec((3,), "N"), force) == ""
    assert channel_disagreement(ChannelSpec((2,), "N"), force) == ""
    assert "unit count is not N" in channel_disagreement(ChannelSpec((3,), "count"), force)
    assert "shape (4, 3) is not (any,)" in channel_disagreement(ChannelSpec((4, 3)), force)
    assert channel_disagreement(ChannelSpec(()), ChannelSpec((1,))) != ""
    with pytest.raises(ValueError):
        ChannelSpec((None,), example=(2, 3))
    with pytest.raises(TypeError):
        ClassifierSpec("x", "x", PluginConfig, "m:f", consumes={"force_n": "2"})


def test_the_bundled_jamming_classifier_says_it_uses_the_force_magnitude(capsys):
    spec = get_registry().get("classifier", "force-rate-jamming").spec
    force = spec.consumes["force_n"]
    assert force.shape == (None,) and force.unit == "N" and "|F|" in force.description
    schema = spec.config.model_json_schema()
    assert "|F|" in schema["properties"]["force_channel"]["description"]
    assert main(["plugins", "--channels"]) == 0
    listing = capsys.readouterr().out
    assert "classifier/force-rate-jamming\n  <- force_n (any,) N: uses |F|" in listing
    assert "sensor/sandbox-force\n  -> force_n (2,) N" in listing
    assert main(["plugins", "--json"]) == 0
    plugins = json.loads(capsys.readouterr().out)["plugins"]
    jamming = next(p for p in plugins if p["name"] == "force-rate-jamming")
    assert jamming["consumes"][0]["channel"] == "force_n"
