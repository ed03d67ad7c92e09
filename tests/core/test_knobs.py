"""Declared knobs (issue 18 §1): the kit's check, the bundled declarations, the listing and
``declared_knobs``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pydantic import Field, model_validator

from hapticframe import Kind, Knob, MapSpec, PluginConfig, RegionConfig, get_registry
from hapticframe._config import RunSettings, validate_file
from hapticframe._knobs import RUN_KNOBS, declared_knobs, knob_problems, resolve_field
from hapticframe.cli._cli import main
from hapticframe.testing import CHECKS, CheckFailure, check_knobs, checks_for

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


class KernelConfig(PluginConfig):
    length_scale_m: float = Field(0.03, gt=0, le=1.0)


class KnobbyConfig(PluginConfig):
    spacing_m: float = Field(0.05, gt=0, le=0.5)
    samples: int = Field(100, ge=2, le=1000)
    min_samples: int = Field(2, ge=1, le=1000)
    method: str = "fast"
    kernel: KernelConfig = Field(default_factory=KernelConfig)
    region: RegionConfig | None = None

    @model_validator(mode="after")
    def _ordered(self) -> KnobbyConfig:
        if self.min_samples > self.samples:
            raise ValueError("min_samples must not exceed samples")
        return self


def _spec(*knobs: Knob, check_config: dict | None = None) -> MapSpec:
    return MapSpec("knobby", "A map with knobs.", KnobbyConfig, "tests.support.labplugin:CellMap",
                   knobs=knobs, check_config=check_config)


def _failure(spec: MapSpec) -> str:
    with pytest.raises(CheckFailure) as info:
        check_knobs(spec)
    return str(info.value)


def test_good_knobs_pass_nested_fields_included():
    check_knobs(_spec(
        Knob("spacing_m", "finer: slower", values=(0.025, 0.05, 0.1)),
        Knob("samples", "more: slower", low=10, high=1000, scale="log", points=3, integer=True),
        Knob("kernel.length_scale_m", "longer: smoother", low=0.01, high=0.1),
        # region is None by default: the nested model is filled in for the knob
        Knob("region.x_max_m", "a wider region: more to search", values=(0.5, 0.75)),
        Knob("method", "the fast method or the exact one", values=("fast", "exact")),
    ))
    check_knobs(_spec())  # no knobs: nothing to check


def test_a_misnamed_field_fails_with_a_close_name():
    message = _failure(_spec(Knob("spacing", "x", values=(0.1, 0.2))))
    assert "knobby" in message and "has no field 'spacing'; did you mean 'spacing_m'?" in message
    message = _failure(_spec(Knob("kernel.length_m", "x", values=(0.1, 0.2))))
    assert "kernel has no field 'length_m'" in message
    message = _failure(_spec(Knob("samples.count", "x", values=(1, 2))))
    assert "samples is not a nested model" in message


def test_a_value_the_field_refuses_fails():
    message = _failure(_spec(Knob("spacing_m", "x", values=(0.05, 0.6))))
    assert "value 0.6 does not validate" in message and "spacing_m" in message
    message = _failure(_spec(Knob("samples", "x", values=(10, 2.5))))
    assert "value 2.5 does not validate" in message
    # accepted by pydantic's coercion, but the sweep would record a string
    message = _failure(_spec(Knob("spacing_m", "x", values=(0.05, "0.1"))))
    assert "value '0.1' becomes 0.1" in message


def test_a_value_is_checked_on_the_check_config_too():
    knob = Knob("samples", "more: slower", values=(10, 50))
    check_knobs(_spec(knob))  # the defaults take it
    message = _failure(_spec(knob, check_config={"min_samples": 20}))
    assert "value 10 does not validate" in message and "min_samples must not exceed" in message


def test_a_range_outside_the_fields_bounds_fails():
    message = _failure(_spec(Knob("spacing_m", "x", low=0.01, high=2.0, scale="log")))
    assert "range high 2 is outside the field's bounds (must be ≤ 0.5)" in message
    message = _failure(_spec(Knob("samples", "x", low=1, high=100, integer=True)))
    assert "range low 1 is outside the field's bounds (must be ≥ 2)" in message
    message = _failure(_spec(Knob("kernel.length_scale_m", "x", low=0.0, high=0.5)))
    assert "range low 0 is outside the field's bounds (must be > 0)" in message


def test_a_knob_that_sweeps_nothing_or_is_declared_twice_fails():
    message = _failure(_spec(Knob("samples", "x", values=(10,))))
    assert "sweeps 1 distinct value(s)" in message
    message = _failure(_spec(Knob("samples", "x", low=10, high=10.4, integer=True)))
    assert "sweeps 1 distinct value(s)" in message
    knob = Knob("samples", "x", values=(10, 20))
    assert "declared more than once" in _failure(_spec(knob, knob))


def test_the_kit_runs_check_knobs_for_every_kind():
    for kind in Kind:
        assert check_knobs in CHECKS[kind], kind
    assert check_knobs in checks_for(_spec())


def test_the_run_loops_knobs_validate_against_the_run_settings():
    for knob in RUN_KNOBS:
        assert knob_problems(RunSettings, knob) == []
    assert resolve_field(RunSettings, "lookahead_steps").default == 64


ISSUE_KNOBS = {
    # The Monte-Carlo std's cost is swept as std_method (monte_carlo against the surrogate):
    # monte_carlo_samples alone bought nothing at the default surrogate std.
    ("map", "bayesian-hilbert-map"): {"hinge_spacing_m", "std_method"},
    ("sensor_model", "failure-zone-kernel"): {"observation_spacing_m"},
    ("feature_extractor", "emd-features"): {"max_sifts"},
    ("feature_extractor", "sparse-coding"): {"pac_atoms", "encode_max_iter"},
    ("classifier", "sf-rnn"): {"gru_units", "gru_layers"},
    ("map", "belief-map"): {"max_points", "update_every"},
    ("planner", "two-phase-coverage"): {"phase2_line_spacing_m"},
}


def test_every_bundled_plugin_with_a_trade_declares_valid_knobs():
    registry = get_registry()
    specs = {(r.spec.kind.value, r.spec.name): r.spec for r in registry}
    for key, fields in ISSUE_KNOBS.items():
        assert fields <= {k.field for k in specs[key].knobs}, key
    for spec in specs.values():
        check_knobs(spec)


def test_declared_knobs_of_an_experiment():
    experiment = validate_file(EXAMPLES / "search-ellipse.yaml")
    pairs = declared_knobs(experiment)
    paths = [f"{cid}.{knob.field}" for cid, knob in pairs]
    assert "bhm.hinge_spacing_m" in paths and "failure-zone.observation_spacing_m" in paths
    assert "planner.phase2_line_spacing_m" in paths and "arm.control_rate_hz" in paths
    assert paths[-2:] == ["run.lookahead_steps", "run.map_update_every_steps"]
    assert not [p for p in paths if p.startswith("wrist.")]  # sandbox-force declares none
    ids = {entry.id for entry in experiment.components}
    assert {cid for cid, _ in pairs} <= ids | {"run"}
    assert [p for p in (f"{c}.{k.field}" for c, k in declared_knobs(experiment, run=False))
            if p.startswith("run.")] == []


def test_plugins_lists_the_knobs(capsys):
    assert main(["plugins", "--knobs"]) == 0
    out = capsys.readouterr().out
    line = next(x for x in out.splitlines() if "hinge_spacing_m" in x)
    assert line.startswith("map/bayesian-hilbert-map") and "0.025, 0.035, 0.05" in line
    assert "finer hinges" in line
    assert any(x.startswith("run ") and "lookahead_steps" in x for x in out.splitlines())
    assert "no knobs:" in out and "sensor_model/contact-point" in out
    assert main(["plugins", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    emd = next(p for p in data["plugins"] if p["name"] == "sparse-coding")
    capped = next(k for k in emd["knobs"] if k["field"] == "encode_max_iter")
    assert capped["values"] == [10, 32, 100, 316, 1000] and capped["scale"] == "log"
    assert {k["field"] for k in data["run_knobs"]} == {"lookahead_steps", "map_update_every_steps"}
