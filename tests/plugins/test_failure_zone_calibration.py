"""Fitting the failure-zone kernel's parameters from recorded movements (issue 29 §2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hapticframe_failure_zone import FailureZoneConfig, fit_failure_zone


def _circle(center: tuple[float, float], radius: float) -> np.ndarray:
    t = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    return np.column_stack([center[0] + radius * np.cos(t), center[1] + radius * np.sin(t)])


def _recording(ratio: float, depths: list[float], lateral: list[float], radius: float = 0.04):
    """Straight movements along +x towards a circle at x = 0.5; jamming starts where the
    plate's distance to the outline falls to ``ratio * depth``, contact at the outline."""
    outline = _circle((0.5, 0.2), radius)
    pos, head, dep, mov, state = [], [], [], [], []
    for m, (d, y) in enumerate(zip(depths, lateral, strict=True)):
        xs = np.arange(0.2, 0.5, 0.001)
        for x in xs:
            dist = float(np.min(np.hypot(outline[:, 0] - x, outline[:, 1] - (0.2 + y))))
            s = 2 if dist < 0.002 else (1 if dist <= ratio * d else 0)
            pos.append((x, 0.2 + y))
            head.append(0.0)
            dep.append(d)
            mov.append(m)
            state.append(s)
            if s == 2:
                break
    return (np.array(pos), np.array(head), np.array(dep), np.array(mov), np.array(state),
            [outline])


def test_recovers_rupture_ratio_and_depth_schedule() -> None:
    depths = [0.044, 0.034, 0.029, 0.0265]
    fit = fit_failure_zone(*_recording(1.2, depths, [0.0, 0.0, 0.0, 0.0]))
    assert fit.rupture_ratio == pytest.approx(1.2, abs=0.03)
    # Vertical plate: r = d cot(beta).
    assert fit.shear_band_angle_deg == pytest.approx(math.degrees(math.atan(1 / 1.2)), abs=1.0)
    assert fit.initial_depth_m == pytest.approx(0.044)
    assert fit.depth_decrement_m == pytest.approx(0.010)
    assert fit.depth_decrement_ratio == pytest.approx(0.5)
    assert fit.sector_half_angle_deg < 5.0  # head-on approaches: the object dead ahead
    # The fitted fields make a valid config.
    config = FailureZoneConfig(**fit.config_overrides())
    assert config.shear_band_angle_deg == pytest.approx(fit.shear_band_angle_deg)


def test_side_approaches_widen_the_sector() -> None:
    fit = fit_failure_zone(*_recording(1.2, [0.044, 0.044], [0.0, 0.05]))
    assert 20.0 < fit.sector_half_angle_deg <= 90.0


def test_refuses_recordings_without_jamming_onset() -> None:
    pos, head, dep, mov, state, outlines = _recording(1.2, [0.044], [0.0])
    with pytest.raises(ValueError, match="no movement became jammed"):
        fit_failure_zone(pos, head, dep, mov, np.zeros_like(state), outlines)
    with pytest.raises(ValueError, match="no samples"):
        fit_failure_zone(np.zeros((0, 2)), [], [], [], [], outlines)
    bad = pos.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        fit_failure_zone(bad, head, dep, mov, state, outlines)
    with pytest.raises(ValueError, match="outline"):
        fit_failure_zone(pos, head, dep, mov, state, [])


def test_fit_runs_names_a_run_that_is_not_a_recording(tmp_path, capsys) -> None:
    from hapticframe_failure_zone.fit_runs import main

    assert main([str(tmp_path / "missing"), "--out", str(tmp_path / "fit.json")]) == 2
    assert "missing: not a recorded run" in capsys.readouterr().err
    assert not (tmp_path / "fit.json").exists()


def _calibration(ratio: float, depths: list[float], lateral: list[float]):
    from hapticframe import CALIBRATION_CLASSES
    from hapticframe.kinds import CalibrationRecording

    pos, head, dep, mov, state, outlines = _recording(ratio, depths, lateral)
    return CalibrationRecording(np.arange(len(state)) * 0.01, pos, head, dep, mov,
                                np.eye(3)[state], CALIBRATION_CLASSES, outlines)


def test_kernel_fit_is_the_train_step_and_its_artifact_loads(tmp_path) -> None:
    from hapticframe.kinds import BuildContext, TrainableSensorModel
    from hapticframe_failure_zone import FailureZoneKernel

    def build(**kw) -> FailureZoneKernel:
        return FailureZoneKernel(FailureZoneConfig(**kw),
                                 BuildContext(id="fz", rng=np.random.default_rng(0)))

    kernel = build()
    assert isinstance(kernel, TrainableSensorModel)
    assert kernel.training_report() == {}
    with pytest.raises(ValueError, match="not been fitted"):
        kernel.save(tmp_path)
    # Two recordings; movement indices are kept apart, so the schedule sees four movements.
    kernel.fit([_calibration(1.2, [0.044, 0.034], [0.0, 0.0]),
                _calibration(1.2, [0.029, 0.0265], [0.0, 0.0])])
    report = kernel.training_report()
    assert report["rupture_ratio"] == pytest.approx(1.2, abs=0.03)
    assert kernel.config.shear_band_angle_deg == pytest.approx(report["shear_band_angle_deg"])
    assert kernel.shear_band_angle_rad == pytest.approx(
        math.radians(report["shear_band_angle_deg"]))
    kernel.save(tmp_path)
    loaded = build(model_dir=str(tmp_path))
    assert loaded.config.shear_band_angle_deg == pytest.approx(report["shear_band_angle_deg"])
    assert loaded.parameters(0.03) == pytest.approx(kernel.parameters(0.03))
    assert loaded.parameters(0.03) != pytest.approx(build().parameters(0.03))
    (tmp_path / FailureZoneKernel.ARTIFACT).write_text('{"config": {"nope": 1}}')
    with pytest.raises(ValueError, match="failure-zone config fields"):
        build(model_dir=str(tmp_path))


def test_calibration_recording_names_bad_input() -> None:
    from hapticframe.kinds import CalibrationRecording

    args = [np.zeros(3), np.zeros((3, 2)), np.zeros(3), np.zeros(3), [0, 0, 1],
            np.eye(3), ("free", "jamming", "contact"), [_circle((0, 0), 0.1)]]
    assert len(CalibrationRecording(*args)) == 3
    bad = list(args)
    bad[1] = np.zeros((2, 2))
    with pytest.raises(ValueError, match="lab-run-7: positions_m"):
        CalibrationRecording(*bad, source="lab-run-7")
    bad = list(args)
    bad[4] = [1, 0, 0]
    with pytest.raises(ValueError, match="must not decrease"):
        CalibrationRecording(*bad)
    bad = list(args)
    bad[7] = []
    with pytest.raises(ValueError, match="known object"):
        CalibrationRecording(*bad)
