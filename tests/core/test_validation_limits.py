"""Issue 26 §3: what ``validate`` must see.

Settings inside their schema ranges that would exhaust memory or loop for ever, fault
schedules a device cannot run, integers too long to read, booleans written for numbers, a
simulated robot without a scene and a workspace outside the searched region: each is
refused at ``validate`` (exit 2, located: file, line, dotted path; sizes with their
estimate), never an internal error, and ``run`` refuses it before writing anything.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, Size, validate_mapping
from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]


def _example(name: str) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load((ROOT / "examples" / name).read_text())
    return data


def _validate(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
              *options: str, suffix: str = ".yaml") -> str:
    """``hapticframe validate`` on ``text``: must exit 2; its stderr."""
    path = tmp_path / f"mutant{suffix}"
    path.write_text(text, encoding="utf-8")
    assert main(["validate", *options, str(path)]) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err and "Traceback" not in err, err
    return err


def _refused(tmp_path: Path, capsys: pytest.CaptureFixture[str], *options: str,
             example: str = "search-ellipse.yaml") -> str:
    """The example with ``--set`` options: refused by validate and by run (nothing written)."""
    text = (ROOT / "examples" / example).read_text()
    err = _validate(tmp_path, capsys, text, *options)
    out = tmp_path / "run"
    assert main(["run", *options, str(tmp_path / "mutant.yaml"), "--out", str(out),
                 "--quiet"]) == 2
    capsys.readouterr()
    assert not out.exists()
    return err


# --- sizes --------------------------------------------------------------------------------

@pytest.mark.parametrize("options, where, estimate", [
    (("--set", "bhm.std_method=monte_carlo", "--set", "bhm.monte_carlo_samples=100000"),
     "maps[1].config.monte_carlo_samples: monte_carlo_samples asks for about", "GiB"),
    (("--set", "planner.phase2_line_spacing_m=1e-9",),
     "planners[0].config.phase2_line_spacing_m: phase2_line_spacing_m asks for about", "GiB"),
    (("--set", "planner.gap_step_deg=1e-9",),
     "planners[0].config.gap_step_deg: gap_step_deg asks for about", "TiB"),
    (("--set", "run.snapshot_spacing_m=1e-9",),
     "run.snapshot_spacing_m: a snapshot of map", "EiB a snapshot"),
    (("--set", "planner.line_spacing_m=5e-324",),
     "planners[0].config.line_spacing_m: line_spacing_m asks for", "unbounded memory"),
    (("--set", "bhm.hinge_spacing_m=5e-324",),  # was an internal OverflowError
     "maps[1].config.hinge_spacing_m:", "inf weights"),
])
def test_sizes_in_range_that_would_exhaust_memory_are_refused_with_the_estimate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: tuple[str, ...], where: str,
    estimate: str,
) -> None:
    err = _refused(tmp_path, capsys, *options)
    line = next((x for x in err.splitlines() if where in x), "")
    assert line.startswith(f"{tmp_path / 'mutant.yaml'}:"), err  # file and line
    assert estimate in line, err


def test_the_belief_map_declares_its_refit_and_snapshots(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _refused(tmp_path, capsys, "--set", "belief.max_points=100000",
                   example="perception-belief-map.yaml")
    assert ".config.max_points: max_points asks for about" in err


def test_the_recurrent_classifiers_declare_their_networks() -> None:
    data = _example("perception-belief-map.yaml")
    classifier = next(c for c in data["classifiers"] if c["type"] == "sf-rnn")
    classifier.setdefault("config", {})["gru_units"] = 4096
    with pytest.raises(ExperimentError) as caught:
        validate_mapping(data)
    assert "gru_units asks for about" in str(caught.value)


def test_a_size_says_what_it_costs_and_refuses_itself_over_the_limits() -> None:
    assert Size("n", "a buffer", bytes=1024.0).problem() is None
    text = Size("n", "a buffer", bytes=3 * 2.0**60, remedy="lower n").problem()
    assert text == "n asks for about 3 EiB (a buffer); the limit is 4 GiB: lower n"
    loop = Size("steps", "a loop", iterations=float("inf")).problem()
    assert loop is not None and "unbounded iterations" in loop
    with pytest.raises(ValueError, match="non-negative"):
        Size("n", "x", bytes=float("nan"))


# --- fault schedules ------------------------------------------------------------------------

_FT300 = """\
schema_version: 1
name: ft300-faults
seed: 1
sensors:
  - id: ft
    type: robotiq-ft300
    config:
      port: emulated
      faults:
        - {entry}
"""


@pytest.mark.parametrize("entry, where, message", [
    ("{kind: stall, rate_hz: .inf}", "faults[0].rate_hz", "finite number"),
    ("{kind: bad_crc, rate_hz: 1.0e12}", "faults[0].rate_hz", "less than or equal to 1000"),
    ("{kind: bad_crc, rate_hz: 1.0e308}", "faults[0].rate_hz", "less than or equal to 1000"),
    ("{kind: bad_crcc, rate_hz: 1}", "faults[0].kind", "did you mean 'bad_crc'"),
    ("{kind: stal, at_s: 1, duration_s: 0.1}", "faults[0].kind", "did you mean 'stall'"),
    ("{kind: bus_overrun, at_s: 1}", "faults[0].kind", "no fault kind 'bus_overrun'"),
    ("{kind: bad_crc, at_s: .nan}", "faults[0].at_s", "finite number"),
    ("{kind: header_in_payload, at_s: 1, params: {offset: 1.0e+15}}", "faults[0]",
     "params.offset of fault kind 'header_in_payload' must be an integer"),
    ("{kind: frame_drop_bytes, at_s: 1, params: {position: 3}}", "faults[0]",
     "reads no parameter 'position'"),
    ("{kind: bad_crc, at_s: 1, rate_hz: 2}", "faults[0]", "exactly one of at_s"),
])
def test_a_fault_the_device_cannot_run_is_refused_where_it_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], entry: str, where: str, message: str
) -> None:
    err = _validate(tmp_path, capsys, _FT300.format(entry=entry))
    assert f"mutant.yaml:10: sensors[0].config.{where}" in err, err
    assert message in err, err


def test_a_dynamixel_position_the_emulator_cannot_hold_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _example("search-ellipse-dynamixel.yaml")
    robot = next(r for r in data["robots"] if r["type"] == "dynamixel")
    robot["config"]["faults"] = [{"kind": "stuffing", "at_s": 1.0,
                                  "params": {"position": 10**15}}]
    err = _validate(tmp_path, capsys, yaml.safe_dump(data, sort_keys=False))
    assert "params.position of fault kind 'stuffing' must lie in" in err


def test_every_device_declares_the_kinds_its_emulator_applies() -> None:
    from hapticframe_barrett import _emulator as barrett
    from hapticframe_barrett._hand_config import PUCK_FAULT_KINDS
    from hapticframe_bno055 import _config as bno055_config
    from hapticframe_bno055 import _emulator as bno055
    from hapticframe_dynamixel import _config as dynamixel_config
    from hapticframe_dynamixel import _emulator as dynamixel
    from hapticframe_robotiq import _config as robotiq_config
    from hapticframe_robotiq import _emulator as robotiq

    assert set(robotiq_config.FAULT_KINDS) == set(robotiq.FAULT_KINDS)
    assert set(bno055_config.FAULT_KINDS) == set(bno055.MODEL_FAULT_KINDS)
    assert set(dynamixel_config.FAULT_KINDS) == set(dynamixel.FAULT_KINDS)
    assert set(PUCK_FAULT_KINDS) == set(barrett.FAULT_KINDS)


def test_the_standard_schedules_validate() -> None:
    from pydantic import TypeAdapter

    from hapticframe.devices import fault_setting
    from hapticframe_barrett._hand_config import PUCK_FAULT_KINDS
    from hapticframe_barrett._hand_robot import STANDARD_FAULTS as hand
    from hapticframe_barrett._wam import STANDARD_FAULTS as wam
    from hapticframe_dynamixel._bus import STANDARD_FAULTS as dynamixel
    from hapticframe_dynamixel._config import FAULT_KINDS as dynamixel_kinds
    from hapticframe_robotiq._config import FAULT_KINDS as robotiq_kinds
    from hapticframe_robotiq._emulator import STANDARD_FAULTS as robotiq

    can = fault_setting(PUCK_FAULT_KINDS, byte_faults=False)
    for setting, schedule in ((fault_setting(robotiq_kinds), robotiq),
                              (fault_setting(dynamixel_kinds), dynamixel),
                              (can, hand), (can, wam)):
        assert len(TypeAdapter(setting).validate_python(list(schedule))) == len(schedule)
    with pytest.raises(ValueError, match="no fault kind 'disconnect'"):
        TypeAdapter(can).validate_python([{"kind": "disconnect", "at_s": 1.0}])


# --- numbers, booleans, the scene, the workspace --------------------------------------------

_LONG = "7" * 5000


@pytest.mark.parametrize("suffix, text", [
    (".yaml", f"schema_version: 1\nname: long\nseed: {_LONG}\n"),
    (".toml", f'schema_version = 1\nname = "long"\nseed = {_LONG}\n'),
    (".json", f'{{"schema_version": 1,\n"name": "long",\n"seed": {_LONG}}}\n'),
])
def test_an_integer_over_4300_digits_is_a_located_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], suffix: str, text: str
) -> None:
    err = _validate(tmp_path, capsys, text, suffix=suffix)
    assert f"mutant{suffix}:3:" in err and "a number of 5000 digits" in err, err


@pytest.mark.parametrize("option, where", [
    ("bhm.hinge_spacing_m=true", "maps[1].config.hinge_spacing_m"),
    ("run.found_within_m=true", "run.found_within_m"),
    ("arm.workspace.x_min_m=false", "robots[0].config.workspace.x_min_m"),
    ("scene.objects[0].center_m[1]=true", "scene.objects[0].center_m[1]"),
])
def test_a_boolean_is_not_a_number(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], option: str, where: str
) -> None:
    err = _refused(tmp_path, capsys, "--set", option)
    assert f"{where}: must be a number, not the boolean" in err, err


def test_a_boolean_still_sets_a_boolean() -> None:
    data = _example("search-ellipse.yaml")
    data["run"]["record"] = False
    assert validate_mapping(data).model.run.record is False


def test_a_simulated_robot_without_a_scene_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _refused(tmp_path, capsys, "--set", "scene=null")
    assert "robots[0]: robot 'arm' (sandbox) simulates the scene, and the experiment has none" \
        in err


def test_a_workspace_outside_the_region_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _refused(tmp_path, capsys, "--set",
                   "arm.workspace={x_min_m: 2, x_max_m: 3, y_min_m: 0, y_max_m: 0.5}")
    assert "robots[0].config.workspace: the workspace of robot 'arm'" in err
    assert "lies outside the region planner 'planner' searches" in err


# --- every plugin declares what its settings cost ---------------------------------------------

#: The fields of the bundled plugins that size an allocation or a loop: each must be declared
#: by its validator with a Size (so that validate estimates it and the kit probes its range).
SIZED_FIELDS = {
    ("map", "bayesian-hilbert-map"): {"hinge_spacing_m", "monte_carlo_samples"},
    ("map", "belief-map"): {"max_points", "max_snapshots"},
    ("map", "gp-occupancy"): {"exact_max_observations", "max_inducing_points"},
    ("map", "occupancy-grid"): {"cell_size_m"},
    ("planner", "coverage"): {"line_spacing_m"},
    ("planner", "two-phase-coverage"): {"line_spacing_m", "phase2_line_spacing_m",
                                        "gap_step_deg", "score_step_m", "grid_spacing_m"},
    ("sensor_model", "failure-zone-kernel"): {"sector_spacing_m"},
    ("feature_extractor", "emd-features"): {"max_sifts", "pac_window_samples",
                                            "pdc_window_samples", "pac_imfs", "pdc_imfs"},
    ("feature_extractor", "sparse-coding"): {"pac_atoms", "pdc_atoms", "electrodes_atoms",
                                             "fit_batch_size", "encode_max_iter"},
    ("classifier", "sf-rnn"): {"gru_units", "window_frames", "batch_size"},
    ("classifier", "fusion-rnn"): {"branch_units", "window_frames", "batch_size"},
    ("classifier", "linear-svm"): {"inputs", "max_iter"},
    ("sensor", "biotac"): {"frames_per_read", "n_trials", "emulator_frames"},
}


def test_every_bundled_plugin_declares_the_fields_that_size_its_work() -> None:
    from hapticframe import get_registry
    from hapticframe._config._checks import validator_results
    from hapticframe.testing._sizes import kit_context

    registry = get_registry()
    for (kind, name), fields in SIZED_FIELDS.items():
        spec = registry.get(kind, name).spec
        config = spec.config.model_validate(spec.check_config or {})
        _, sizes = validator_results(spec.load_validator(), config, kit_context(spec))
        assert fields <= {size.field for size in sizes}, (name, fields)
