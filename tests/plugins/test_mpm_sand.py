"""The ``mpm-sand`` world: its response library (no engine needed) and the world's forces."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hapticframe import Circle, Material, Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement
from hapticframe_mpm_sand import (
    MpmSandRobot,
    MpmSandRobotConfig,
    ResponseLibrary,
    bundled_library,
    fit_power_law,
    load_library,
    save_library,
)
from hapticframe_mpm_sand._library import material_parameters

SCENE = Scene(objects=[Circle(center_m=(0.30, 0.25), radius_m=0.03)])


def _robot(scene: Scene = SCENE, **config: object) -> MpmSandRobot:
    context = BuildContext(id="arm", rng=np.random.default_rng(3), scene=scene)
    return MpmSandRobot(MpmSandRobotConfig(**config), context)


def _rake(robot: MpmSandRobot, start: tuple[float, float], end: tuple[float, float]
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    robot.begin(ExploratoryMovement(start, end, speed_m_per_s=0.05))
    while robot.step() is not None:
        pass
    truth = robot.ground_truth
    return truth.positions_m, truth.forces_n, truth.states


def _tiny_library(**changes: np.ndarray) -> ResponseLibrary:
    arrays = {
        "depths_m": np.array([0.02, 0.04]),
        "radii_m": np.array([0.01, 0.03]),
        "offsets_u": np.array([0.0, 1.0]),
        "s_m": np.array([-0.04, -0.02, 0.0]),
        "travel_m": np.array([0.0, 0.05]),
        "free_drag_n": np.array([[1.0, 1.0], [4.0, 4.0]]),
        "ratio_x": np.ones((2, 2, 2, 3)),
        "ratio_y": np.zeros((2, 2, 2, 3)),
        "settings": np.array([0.0075, 2, 0.03, 200, 0.9004, 0.236, 1600, 0.05, 1.0]),
    }
    arrays.update(changes)
    return ResponseLibrary(**arrays)


def test_the_power_law_fit_recovers_a_known_exponent():
    depths = np.array([0.01, 0.02, 0.05])
    c, n = fit_power_law(depths, 3.0 * depths**1.7)
    assert n == pytest.approx(1.7, rel=1e-9)
    assert c == pytest.approx(3.0, rel=1e-9)
    with pytest.raises(ValueError, match="two distinct depths"):
        fit_power_law(np.array([0.02]), np.array([1.0]))
    with pytest.raises(ValueError, match="positive"):
        fit_power_law(np.array([0.02, 0.03]), np.array([1.0, math.nan]))


def test_interpolation_hits_the_nodes_and_clamps_at_the_edges():
    ratio = np.ones((2, 2, 2, 3))
    ratio[1, 1, 0] = [1.0, 1.5, 3.0]
    library = _tiny_library(ratio_x=ratio)
    assert library.ratio(0.04, 0.03, 0.0, -0.02) == (1.5, 0.0)
    assert library.ratio(0.04, 0.03, 0.0, -0.01)[0] == pytest.approx(2.25)
    # Halfway in depth: halfway between the rows.
    assert library.ratio(0.03, 0.03, 0.0, 0.0)[0] == pytest.approx(2.0)
    # Beyond every edge: the edge's value.
    assert library.ratio(0.2, 0.5, -1.0, 1.0)[0] == pytest.approx(3.0)
    # Free drag below the grid follows the fitted law (here n = 2 exactly).
    assert library.drag_law[1] == pytest.approx(2.0)
    assert library.free_drag(0.01, 0.03) == pytest.approx(0.25)


def test_a_bad_library_is_refused_with_the_array_named(tmp_path: Path):
    with pytest.raises(ValueError, match="'ratio_x' holds a non-finite"):
        _tiny_library(ratio_x=np.full((2, 2, 2, 3), np.nan))
    with pytest.raises(ValueError, match="axis 's'"):
        _tiny_library(ratio_y=np.zeros((2, 2, 2, 4)))
    with pytest.raises(ValueError, match="'depths_m' must be non-empty and increasing"):
        _tiny_library(depths_m=np.array([0.04, 0.02]))
    path = tmp_path / "lib.npz"
    save_library(path, _tiny_library())
    assert load_library(path).ratio(0.02, 0.01, 0.0, -0.04) == (1.0, 0.0)
    np.savez(path, depths_m=np.array([0.02]))
    with pytest.raises(ValueError, match=r"lib\.npz: library lacks array"):
        load_library(path)


def test_the_bundled_library_is_the_examples_sand():
    library = bundled_library()
    friction, dilatancy = material_parameters(42.0, 12.0)
    assert library.settings[4] == pytest.approx(friction, abs=1e-3)
    assert library.settings[5] == pytest.approx(dilatancy, abs=1e-3)
    assert np.all(library.steady_drag_n > 0)
    # Deeper is harder going in the engine, too.
    assert np.all(np.diff(library.steady_drag_n) > 0)


def test_free_raking_gives_the_librarys_drag_against_the_motion():
    robot = _robot(drag_fluctuation_fraction=0.0)
    positions, forces, states = _rake(robot, (0.05, 0.10), (0.20, 0.10))
    assert np.all(states == 0)
    library = robot.library
    travelled = positions[:, 0] - 0.05
    expected = [library.free_drag(0.044, t) for t in travelled]
    np.testing.assert_allclose(-forces[:, 0], expected, rtol=1e-12)
    np.testing.assert_allclose(forces[:, 1], 0.0, atol=1e-12)


def test_the_force_rises_ahead_of_an_object_and_contact_is_added_after_touch():
    free = _robot(scene=Scene(objects=[]), drag_fluctuation_fraction=0.0)
    _, free_forces, _ = _rake(free, (0.10, 0.25), (0.29, 0.25))
    robot = _robot(drag_fluctuation_fraction=0.0)
    positions, forces, states = _rake(robot, (0.10, 0.25), (0.29, 0.25))
    # The run with the object may end early, at the force limit, once in contact.
    ratio = forces[:, 0] / free_forces[: len(forces), 0]
    ahead = positions[:, 0] - 0.27  # the circle's leading point is at x = 0.27
    # Farther ahead than the library's runs saw nothing; 1 cm before the leading point the
    # engine's rise; past it contact.
    far = ahead < float(robot.library.s_m[0]) - 0.003
    assert far.any()
    assert np.all(np.abs(ratio[far] - 1.0) < 1e-12)
    near = (ahead > -0.012) & (ahead < -0.008)
    assert np.all(ratio[near] > 1.1)
    assert np.all(states[near] == 1)
    touching = ahead > 0.001
    assert np.all(states[touching] == 2)
    # The spring: the contact adds stiffness x penetration on top of the sand's force.
    assert -forces[-1, 0] > -forces[touching][0, 0] + 3000.0 * 0.01


def test_an_object_on_the_left_pushes_the_plate_to_the_right():
    robot = _robot(drag_fluctuation_fraction=0.0)
    # Plate line 3 cm to the right (-y) of the centre: the object is on the plate's left.
    _, forces, _ = _rake(robot, (0.10, 0.22), (0.265, 0.22))
    mirrored = _robot(drag_fluctuation_fraction=0.0)
    _, mirror_forces, _ = _rake(mirrored, (0.10, 0.28), (0.265, 0.28))
    np.testing.assert_allclose(forces[:, 0], mirror_forces[:, 0], rtol=1e-12)
    np.testing.assert_allclose(forces[:, 1], -mirror_forces[:, 1], atol=1e-12)
    assert np.any(forces[:, 1] != 0.0)


def test_a_scene_of_other_sand_is_refused_with_the_build_command():
    scene = Scene(material=Material(friction_angle_deg=30.0, dilation_angle_deg=5.0),
                  objects=[])
    with pytest.raises(ValueError, match=r"build_library --friction-angle-deg 30"):
        _robot(scene=scene)
    with pytest.raises(ValueError, match=r"no bundled response library at voxel_size_m 0\.02"):
        _robot(voxel_size_m=0.02)


def test_the_physics_checks_say_what_to_install_without_the_engine() -> None:
    import importlib.util
    import types

    from hapticframe import UsageError
    from hapticframe_mpm_sand._checks import run_physics_checks

    if importlib.util.find_spec("newton") is not None:
        pytest.skip("the physics extra is installed: the checks would run the engine")
    options = types.SimpleNamespace(quick=True, seed=0, echo=lambda _line: None)
    with pytest.raises(UsageError, match=r"hapticframe\[physics\]"):
        run_physics_checks(options)
