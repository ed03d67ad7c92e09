"""Shape tables of the ``mpm-sand`` response library (issue 32, §4): engine runs towards
ellipses and boxes at a yaw, matched to scene objects and met as themselves, not as
equivalent cylinders. No engine needed: synthetic tables and the run geometry."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticframe import Circle, Ellipse, Polygon, Scene
from hapticframe.kinds import BuildContext
from hapticframe_mpm_sand import (
    MpmSandRobot,
    MpmSandRobotConfig,
    ResponseLibrary,
    load_library,
    save_library,
)
from hapticframe_mpm_sand._engine import RakeCase, _inside_footprint, _prism_mesh, object_footprint
from hapticframe_mpm_sand.build_library import (
    PLATE_HALF_WIDTH_M,
    TRAVEL_M,
    ShapeSpec,
    parse_shape,
    shape_case,
)
from tests.plugins.test_mpm_sand import _rake

ELLIPSE = ShapeSpec("ellipse", (0.035, 0.025))
BOX = ShapeSpec("box", (0.035, 0.025))
S_M = np.array([-0.04, -0.02, 0.0])
YAWS = np.array([0.0, 45.0, 90.0])
OFFSETS = np.array([-1.0, 0.0, 1.0])


def _library(shape_x: np.ndarray | None = None, shape_y: np.ndarray | None = None,
             shapes: tuple[ShapeSpec, ...] = (ELLIPSE, BOX)) -> ResponseLibrary:
    table = (2, len(shapes), YAWS.size, OFFSETS.size, S_M.size)
    return ResponseLibrary(
        depths_m=np.array([0.02, 0.044]), radii_m=np.array([0.01, 0.03]),
        offsets_u=np.array([0.0, 1.0]), s_m=S_M, travel_m=np.array([0.0, 0.05]),
        free_drag_n=np.array([[1.0, 1.0], [4.0, 4.0]]),
        ratio_x=np.ones((2, 2, 2, 3)), ratio_y=np.zeros((2, 2, 2, 3)),
        settings=np.array([0.0075, 2, 0.0075, 200, 0.9004, 0.236, 1600, 0.05, 1.0]),
        shape_outlines_m=np.stack([spec.outline() for spec in shapes]),
        shape_yaws_deg=YAWS, shape_offsets_u=OFFSETS,
        shape_ratio_x=np.ones(table) if shape_x is None else shape_x,
        shape_ratio_y=np.zeros(table) if shape_y is None else shape_y,
    )


def _box(center: tuple[float, float], orientation_deg: float, a: float = 0.035,
         b: float = 0.025) -> Polygon:
    return Polygon(center_m=center, orientation_deg=orientation_deg,
                   vertices_m=[(a, b), (-a, b), (-a, -b), (a, -b)])


def test_an_outline_matches_its_own_table_turned_by_a_quarter_and_not_the_other_shape():
    library = _library()
    ellipse = Ellipse(center_m=(0.0, 0.0), semi_axes_m=(0.035, 0.025))
    assert library.match_shape(ellipse.outline(300)) == (0, 0.0)
    # The same ellipse given with its axes swapped is the table's, turned by 90 degrees.
    swapped = Ellipse(center_m=(0.0, 0.0), semi_axes_m=(0.025, 0.035))
    assert library.match_shape(swapped.outline(300)) == (0, 90.0)
    assert library.match_shape(_box((0.0, 0.0), 0.0).outline(300)) == (1, 0.0)
    # A circle, or an ellipse of another size, has no table: it is met as a cylinder.
    assert library.match_shape(Circle(center_m=(0, 0), radius_m=0.03).outline(300)) is None
    small = Ellipse(center_m=(0.0, 0.0), semi_axes_m=(0.02, 0.01))
    assert library.match_shape(small.outline(300)) is None


def test_a_yaw_and_its_mirror_give_the_same_drag_and_opposite_side_force():
    shape_x = np.ones((2, 2, 3, 3, 3))
    shape_y = np.zeros((2, 2, 3, 3, 3))
    # At 45 degrees with the object on the left: a rise, and a side force.
    shape_x[1, 0, 1, 2] = [1.0, 1.4, 2.0]
    shape_y[1, 0, 1, 2] = [0.0, 0.3, 0.5]
    library = _library(shape_x, shape_y)
    assert library.shape_ratio(0.044, 0, 45.0, 1.0, -0.02) == pytest.approx((1.4, 0.3))
    # Mirrored across the heading: -45 degrees, the object on the right.
    assert library.shape_ratio(0.044, 0, -45.0, -1.0, -0.02) == pytest.approx((1.4, -0.3))
    # Half a turn is the same shape (symmetric about both axes).
    assert library.shape_ratio(0.044, 0, 225.0, 1.0, -0.02) == pytest.approx((1.4, 0.3))
    # Between grid yaws: linear; and the other side of the 45-degree run is untouched.
    assert library.shape_ratio(0.044, 0, 22.5, 1.0, -0.02)[0] == pytest.approx(1.2)
    assert library.shape_ratio(0.044, 0, 45.0, -1.0, -0.02) == pytest.approx((1.0, 0.0))


def test_a_library_with_shape_tables_round_trips_and_an_old_file_has_none(tmp_path: Path):
    shape_x = np.ones((2, 2, 3, 3, 3))
    shape_x[0, 1, 2, 1] = [1.0, 1.2, 1.7]
    path = tmp_path / "shapes.npz"
    save_library(path, _library(shape_x))
    loaded = load_library(path)
    assert loaded.shape_count == 2
    assert loaded.shape_ratio(0.02, 1, 90.0, 0.0, 0.0)[0] == pytest.approx(1.7)
    old = {name: np.asarray(getattr(loaded, name)) for name in
           ("depths_m", "radii_m", "offsets_u", "s_m", "travel_m", "free_drag_n", "ratio_x",
            "ratio_y", "settings")}
    np.savez(tmp_path / "old.npz", **old)  # type: ignore[arg-type]
    assert load_library(tmp_path / "old.npz").shape_count == 0
    with pytest.raises(ValueError, match=r"'shape_yaws_deg' must lie in 0 \.\.\. 90"):
        ResponseLibrary(**{**old, "shape_outlines_m": np.stack([ELLIPSE.outline()]),
                           "shape_yaws_deg": np.array([0.0, 120.0]),
                           "shape_offsets_u": OFFSETS,
                           "shape_ratio_x": np.ones((2, 1, 2, 3, 3)),
                           "shape_ratio_y": np.zeros((2, 1, 2, 3, 3))})


def _robot(library_path: Path, scene: Scene) -> MpmSandRobot:
    context = BuildContext(id="arm", rng=np.random.default_rng(3), scene=scene)
    return MpmSandRobot(MpmSandRobotConfig(library_path=str(library_path),
                                           drag_fluctuation_fraction=0.0), context)


def _forces(robot: MpmSandRobot, start: tuple[float, float], end: tuple[float, float]
            ) -> tuple[np.ndarray, np.ndarray]:
    positions, forces, _states = _rake(robot, start, end)
    return positions, forces


def test_the_world_meets_a_matching_object_through_its_table_at_its_yaw(tmp_path: Path):
    shape_x = np.ones((2, 2, 3, 3, 3))
    shape_x[:, 1, 0, 1] = [1.0, 2.0, 3.0]  # box, yaw 0, dead ahead: a rise
    shape_x[:, 1, 2, 1] = [1.0, 1.25, 1.5]  # box, yaw 90: a smaller one
    path = tmp_path / "lib.npz"
    save_library(path, _library(shape_x))
    # A box turned by 90 degrees in the map, raked along +y: yaw 0 to the heading.
    scene = Scene(objects=[_box((0.30, 0.30), 90.0)])
    robot = _robot(path, scene)
    assert robot.world.shape_tables == [1]  # type: ignore[attr-defined]
    positions, forces = _forces(robot, (0.30, 0.20), (0.30, 0.262))
    ahead = positions[:, 1] - 0.265  # the box's foremost point: 3.5 cm before its centre
    at = np.argmin(np.abs(ahead + 0.02))
    assert -forces[at, 1] / 4.0 == pytest.approx(2.0, rel=0.05)
    # Raked along +x it meets the box's long side: yaw 90.
    robot = _robot(path, scene)
    positions, forces = _forces(robot, (0.20, 0.30), (0.272, 0.30))
    at = np.argmin(np.abs(positions[:, 0] - 0.275 + 0.02))
    assert -forces[at, 0] / 4.0 == pytest.approx(1.25, rel=0.05)
    # An object with no table is met as its equivalent cylinder (ratio 1 in these tables).
    robot = _robot(path, Scene(objects=[Circle(center_m=(0.30, 0.30), radius_m=0.03)]))
    assert robot.world.shape_tables == [None]  # type: ignore[attr-defined]
    positions, forces = _forces(robot, (0.20, 0.30), (0.26, 0.30))
    np.testing.assert_allclose(-forces[:, 0], 4.0, rtol=1e-9)


def test_a_shape_run_puts_the_foremost_point_a_travel_ahead_and_the_offset_across():
    for spec in (ELLIPSE, BOX):
        for yaw in (0.0, 30.0, 90.0):
            case = shape_case(0.03, spec, yaw, 1.0)
            outline = object_footprint(case)
            front = case.object_x_m + outline[:, 0].min()
            assert front == pytest.approx(RakeCase().start_x_m + TRAVEL_M)
            low = case.lateral_offset_m + outline[:, 1].min()
            high = case.lateral_offset_m + outline[:, 1].max()
            half_across = (high - low) / 2
            # Offset u = 1: the extent's centre is one (half-extent + plate half-width) left.
            assert (low + high) / 2 == pytest.approx(half_across + PLATE_HALF_WIDTH_M)
    with pytest.raises(ValueError, match="offsets >= 0"):
        shape_case(0.03, BOX, 0.0, -0.5)


def test_the_prism_mesh_and_footprint_cover_the_shape():
    case = RakeCase(object_shape="box", object_half_extents_m=(0.03, 0.01), object_yaw_deg=90)
    outline = object_footprint(case)
    inside = _inside_footprint(np.array([[0.0, 0.025], [0.0, -0.029], [0.02, 0.0]]), outline)
    assert inside.tolist() == [True, True, False]
    vertices, faces = _prism_mesh(outline, 0.05)
    assert vertices.shape == (10, 3) and faces.size == 4 * 4 * 3
    assert vertices[:, 2].min() == pytest.approx(-0.025)
    # Every triangle's normal points away from the axis (outward) or along z (a cap).
    tri = vertices[faces.reshape(-1, 3)]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = tri.mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", normal, centre) > 0)


def test_bad_shape_specs_and_cases_are_refused():
    assert parse_shape("ellipse:0.035,0.025") == ELLIPSE
    for text in ("ellipse", "disc:0.03,0.03", "box:0.03", "box:0.03,-0.01"):
        with pytest.raises(ValueError, match="kind:a,b"):
            parse_shape(text)
    with pytest.raises(ValueError, match="object_shape 'torus'"):
        RakeCase(object_shape="torus")
    with pytest.raises(ValueError, match="positive object_half_extents_m"):
        RakeCase(object_shape="box")


def test_the_reach_of_each_table_is_read_from_the_library():
    from hapticframe_mpm_sand._checks import library_reach

    shape_x = np.ones((2, 2, 3, 3, 3))
    shape_x[1, 0, 0, 1] = [1.2, 1.5, 1.0]  # ellipse, yaw 0, dead ahead: from the start
    shape_x[1, 0, 1, 2] = [1.0, 1.3, 1.0]  # ellipse, yaw 45, left: from 2 cm, to the side
    reach = {(r.depth_m, r.label): r for r in library_reach(_library(shape_x))}
    ahead = reach[(0.044, "shape 0 yaw 0 deg")]
    assert ahead.ahead_m == pytest.approx(0.04) and ahead.ahead_at_edge
    assert ahead.lateral_u == 0.0 and not ahead.lateral_at_edge
    side = reach[(0.044, "shape 0 yaw 45 deg")]
    assert side.ahead_m == 0.0
    assert side.lateral_u == 1.0 and side.lateral_at_edge
    assert reach[(0.02, "cylinder r=3 cm")].ahead_m == 0.0


def test_the_held_out_set_reads_the_librarys_shapes_and_settings():
    from hapticframe_mpm_sand.held_out import default_configurations, settings_of, spec_of

    assert spec_of(ELLIPSE.outline()) == ELLIPSE
    assert spec_of(BOX.outline()) == BOX
    library = _library()
    configs = default_configurations(library)
    shapes = [c for c in configs if "shape" in c]
    assert [c["shape"] for c in shapes] == [ELLIPSE, ELLIPSE, BOX, BOX]
    # Every held-out configuration is off the library's grid.
    for config in configs:
        assert config["depth_m"] not in library.depths_m
        if "shape" in config:
            assert config["yaw_deg"] not in library.shape_yaws_deg
    settings = settings_of(library)
    assert (settings.step_s, settings.max_iterations) == (0.0075, 200)


def test_the_build_command_refuses_a_bad_grid_with_exit_2(capsys: pytest.CaptureFixture[str]):
    from hapticframe_mpm_sand.build_library import main

    assert main(["--out", "x.npz", "--shape", "disc:0.03"]) == 2
    assert "kind:a,b" in capsys.readouterr().err
    assert main(["--out", "x.npz", "--travel-m", "0.001"]) == 2
    assert "travel_m 0.001" in capsys.readouterr().err
    assert main(["--out", "x.npz", "--yaws-deg", "0,120"]) == 2
    assert "0 ... 90" in capsys.readouterr().err
