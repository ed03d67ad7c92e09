"""The resolution convergence study (``python -m hapticframe_mpm_sand.convergence``).

The first tests replace the engine by a synthetic rake whose answer is known (numpy only);
the last runs the engine itself at one coarse cell size and is skipped without ``newton``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from hapticframe_mpm_sand._engine import EngineSettings, RakeCase, RakeResult
from hapticframe_mpm_sand.build_library import TRAVEL_M
from hapticframe_mpm_sand.convergence import main

#: The synthetic force ratio jumps from 1 to this at ONSET_M before the leading point.
JUMP = 1.5
ONSET_M = 0.03


def fake_rake(case: RakeCase, settings: EngineSettings, seed: int) -> RakeResult:
    """Steps as the engine takes them; free drag 2 N per cm of cell size (a resolution
    dependence to recover), times JUMP from ONSET_M before an object's leading point."""
    step = case.speed_m_per_s * settings.step_s
    n = math.ceil(case.travel_m / step)
    x = np.asarray(case.start_x_m + step * (np.arange(n) + 1), dtype=np.float64)
    drag = np.full(n, 200.0 * settings.voxel_size_m)
    if case.object_radius_m > 0:
        s = x - (case.object_x_m - case.object_radius_m)
        drag = np.where(s >= -ONSET_M, JUMP * drag, drag)
    force = np.zeros((n, 3))
    force[:, 0] = -drag
    particles = round(1e-4 / settings.voxel_size_m**3)
    return RakeResult(x_m=x, force_n=force, particle_count=particles, cpu_s=0.5 * particles,
                      wall_s=0.6 * particles)


def test_the_study_writes_every_cell_size_with_the_known_answer(tmp_path: Path) -> None:
    code = main(["--out", str(tmp_path), "--voxel-sizes-m", "0.01,0.005"], rake_fn=fake_rake)
    assert code == 0
    result = json.loads((tmp_path / "convergence.json").read_text())
    assert (tmp_path / "convergence.png").stat().st_size > 10_000
    assert result["depth_m"] == 0.044 and result["radius_m"] == 0.03
    rows = result["rows"]
    assert [r["voxel_size_m"] for r in rows] == [0.01, 0.005]
    assert [r["particles"] for r in rows] == [100, 800]
    for row, voxel in zip(rows, (0.01, 0.005), strict=True):
        assert row["free_drag_n"] == pytest.approx(200.0 * voxel)
        # The bench's onset looks only after half the travel: it sees the rise from there.
        assert row["onset_limit_m"] == pytest.approx(TRAVEL_M / 2, abs=3e-3)
        assert row["onset_distance_m"] == row["onset_limit_m"] < ONSET_M
        # Looked for after 1 cm of travel, the onset is the jump, blurred by the smoothing
        # (one cell of travel) by half a window either way.
        assert row["startup_m"] == 0.01
        assert row["onset_after_startup_limit_m"] == pytest.approx(TRAVEL_M - 0.01, abs=3e-3)
        assert abs(row["onset_after_startup_m"] - ONSET_M) <= voxel / 2 + 1.5e-3
        assert row["ratio_at_2cm"] == pytest.approx(JUMP)
        assert row["ratio_at_1cm"] == pytest.approx(JUMP)
        assert row["cpu_s"] == pytest.approx(2 * 0.5 * row["particles"])
        assert len(row["s_m"]) == len(row["ratio"]) == row["steps"]
        assert row["s_m"][-1] == pytest.approx(0.0, abs=2e-3)
        assert row["s_m"][0] == pytest.approx(-TRAVEL_M, abs=2e-3)


def test_the_iteration_cap_reaches_the_engine_and_the_record(tmp_path: Path) -> None:
    caps: list[int] = []

    def recording(case: RakeCase, settings: EngineSettings, seed: int) -> RakeResult:
        caps.append(settings.max_iterations)
        return fake_rake(case, settings, seed)

    assert main(["--out", str(tmp_path), "--voxel-sizes-m", "0.01", "--max-iterations", "400"],
                rake_fn=recording) == 0
    assert caps and set(caps) == {400}
    assert json.loads((tmp_path / "convergence.json").read_text())["max_iterations"] == 400


def test_no_rise_gives_onset_zero(tmp_path: Path) -> None:
    def flat(case: RakeCase, settings: EngineSettings, seed: int) -> RakeResult:
        return fake_rake(RakeCase(depth_m=case.depth_m, travel_m=case.travel_m), settings, seed)

    assert main(["--out", str(tmp_path), "--voxel-sizes-m", "0.01"], rake_fn=flat) == 0
    row = json.loads((tmp_path / "convergence.json").read_text())["rows"][0]
    assert row["onset_distance_m"] == row["onset_after_startup_m"] == 0.0
    assert row["ratio_at_1cm"] == pytest.approx(1.0)


@pytest.mark.parametrize("argv", [
    ["--voxel-sizes-m", "0.01,-0.005"],
    ["--voxel-sizes-m", "ten"],
    ["--depth-m", "0"],
    ["--dilation-angle-deg", "50"],
    ["--max-iterations", "0"],
    ["--max-iterations", "many"],
])
def test_bad_input_exits_2_without_running(tmp_path: Path, argv: list[str],
                                            capsys: pytest.CaptureFixture[str]) -> None:
    def never(case: RakeCase, settings: EngineSettings, seed: int) -> RakeResult:
        raise AssertionError("the engine ran on bad input")

    with pytest.raises(SystemExit) as exit_info:
        main(["--out", str(tmp_path), *argv], rake_fn=never)
    assert exit_info.value.code == 2
    assert "error:" in capsys.readouterr().err
    assert not (tmp_path / "convergence.json").exists()


@pytest.mark.slow
def test_the_engine_at_one_coarse_cell_size(tmp_path: Path) -> None:
    pytest.importorskip("newton")
    assert main(["--out", str(tmp_path), "--voxel-sizes-m", "0.01", "--step-s", "0.05"]) == 0
    row = json.loads((tmp_path / "convergence.json").read_text())["rows"][0]
    assert row["free_drag_n"] > 0.5
    assert row["particles"] > 1000
    assert row["ratio_at_1cm"] > 1.1
    assert row["onset_distance_m"] > 0.005
