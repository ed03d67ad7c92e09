"""Settings that validated but could not run (issue 36 §2) are refused by ``validate``,
located at their field with the reason and the bound: a ramp so slow that a movement never
ends, a planner depth of 0, a jamming filter cutoff the classifier cannot represent, and a
thread count larger than the machine's."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe import ExperimentError, validate_file
from hapticframe.threads import machine_cpus

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "search-ellipse.yaml"


def _with(tmp_path: Path, section: str, index: int, run: dict[str, Any] | None = None,
          **config: Any) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    data[section][index].setdefault("config", {}).update(config)
    data.setdefault("run", {}).update(run or {})
    path = tmp_path / "experiment.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _refused(path: Path, field: str) -> str:
    with pytest.raises(ExperimentError) as caught:
        validate_file(path)
    issues = [i for i in caught.value.issues if i.path == field]
    assert issues, [f"{i.path}: {i.message}" for i in caught.value.issues]
    assert all(i.line is not None for i in issues)
    return issues[0].message


def test_the_example_validates(tmp_path: Path) -> None:
    validate_file(_with(tmp_path, "robots", 0, acceleration_m_per_s2=0.5))


def test_an_acceleration_near_zero_is_refused_by_its_field(tmp_path: Path) -> None:
    message = _refused(_with(tmp_path, "robots", 0, acceleration_m_per_s2=1e-9),
                       "robots[0].config.acceleration_m_per_s2")
    assert "0.001" in message, message


@pytest.mark.parametrize("acceleration", [1e-3, 0.003])
def test_a_ramp_too_slow_to_end_a_movement_within_the_run_s_steps(
        tmp_path: Path, acceleration: float) -> None:
    run = {"max_steps_per_movement": 3000}  # 30 s at 100 Hz; the diagonal alone takes 18 s
    message = _refused(_with(tmp_path, "robots", 0, run, acceleration_m_per_s2=acceleration),
                       "robots[0].config.acceleration_m_per_s2")
    assert "run.max_steps_per_movement (3000)" in message and "at least" in message, message
    least = float(message.split("at least ")[1].split(" ")[0])
    validate_file(_with(tmp_path, "robots", 0, run, acceleration_m_per_s2=least * 1.01))


def test_a_planner_depth_of_zero(tmp_path: Path) -> None:
    message = _refused(_with(tmp_path, "planners", 0, depth_m=0.0),
                       "planners[0].config.depth_m")
    assert "greater than 0" in message, message


@pytest.mark.parametrize("cutoff", [1e-9, 1e-300])
def test_a_cutoff_the_classifier_cannot_represent(tmp_path: Path, cutoff: float) -> None:
    message = _refused(_with(tmp_path, "classifiers", 0, cutoff_hz=cutoff),
                       "classifiers[0].config")
    assert "cutoff_hz" in message and "at least" in message and "NaN" in message, message


def test_a_cutoff_at_the_bound_filters_to_finite_values() -> None:
    import numpy as np

    from hapticframe.filters import MIN_CUTOFF_RATIO, butterworth_sos, sos_filter, sos_step_state

    for order in (1, 2, 3, 4):
        sos = butterworth_sos(MIN_CUTOFF_RATIO * 100.0, 100.0, order)
        out, _ = sos_filter(sos, np.full(200, 7.0), 7.0 * sos_step_state(sos))
        np.testing.assert_allclose(out, 7.0, rtol=1e-5)
        with pytest.raises(ValueError, match="smallest cutoff"):
            butterworth_sos(0.5 * MIN_CUTOFF_RATIO * 100.0, 100.0, order)


def test_more_blas_threads_than_the_machine_has(tmp_path: Path) -> None:
    message = _refused(_with(tmp_path, "maps", 1, blas_threads=1024),
                       "maps[1].config.blas_threads")
    assert f"the {machine_cpus()} CPUs" in message, message
    validate_file(_with(tmp_path, "maps", 1, blas_threads=machine_cpus()))
