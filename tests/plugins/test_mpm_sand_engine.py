"""The engine's two physical checks on a tiny configuration (the ``physics`` extra).

Skipped without ``newton`` (``pip install 'hapticframe[physics]'``; CI does not install it:
about 480 MB and a minute of kernel compilation on first use). The bench suite
``physics-checks`` runs the same checks at full resolution.
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe_mpm_sand import engine_available

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not engine_available(),
                       reason="needs the physics extra: pip install 'hapticframe[physics]'"),
]

#: 1 cm cells, 50 ms steps: about 1,600 particles, a second or two per run once compiled.
TINY = dict(voxel_size_m=0.01, step_s=0.05)


def test_free_drag_grows_with_depth_and_repeats_bitwise():
    from hapticframe_mpm_sand._checks import drag_depth_check
    from hapticframe_mpm_sand._engine import EngineSettings, RakeCase, rake

    settings = EngineSettings(**TINY)  # type: ignore[arg-type]
    check = drag_depth_check(settings, (0.02, 0.03, 0.044), travel_m=0.03)
    assert np.all(np.diff(check.steady_drag_n) > 0)
    # The dissertation's account says about 2; the engine gives less (docs/physics-world.md),
    # but drag must grow faster than depth and slower than its cube.
    assert 1.0 < check.exponent < 3.0
    case = RakeCase(depth_m=0.03, travel_m=0.01)
    first, second = rake(case, settings, seed=4), rake(case, settings, seed=4)
    np.testing.assert_array_equal(first.force_n, second.force_n)
    assert not np.array_equal(first.force_n, rake(case, settings, seed=5).force_n)


def test_the_force_rises_ahead_of_a_buried_cylinder():
    from hapticframe_mpm_sand._checks import rise_check
    from hapticframe_mpm_sand._engine import EngineSettings

    check = rise_check(EngineSettings(**TINY), depth_m=0.044, radius_m=0.03)  # type: ignore[arg-type]
    assert check.ratio_at_1cm > 1.1
    assert check.ratio_at_1cm > check.ratio_at_2cm > 0.9
    assert check.rise_distance_m > 0.005


def test_a_box_ahead_raises_the_force_and_one_far_to_the_side_does_not():
    from hapticframe_mpm_sand._engine import EngineSettings, RakeCase, rake
    from hapticframe_mpm_sand.build_library import ShapeSpec, shape_case, smooth

    settings = EngineSettings(**TINY)  # type: ignore[arg-type]
    box = ShapeSpec("box", (0.03, 0.02))
    free = rake(RakeCase(depth_m=0.044, travel_m=0.055), settings)
    ahead = rake(shape_case(0.044, box, 30.0, 0.0), settings)
    aside = rake(shape_case(0.044, box, 30.0, 2.5), settings)

    def ratio_at_1cm(run):  # type: ignore[no-untyped-def]
        s = run.x_m - (RakeCase().start_x_m + 0.055)
        ratio = smooth(-run.force_n[:, 0], 3) / smooth(-free.force_n[:, 0], 3)
        return float(np.interp(-0.01, s, ratio))

    assert ratio_at_1cm(ahead) > 1.1
    assert abs(ratio_at_1cm(aside) - 1.0) < 0.1
