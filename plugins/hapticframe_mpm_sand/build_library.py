"""Build the response library from engine runs (needs the ``physics`` extra).

::

    OMP_NUM_THREADS=1 nice -n 10 python -m hapticframe_mpm_sand.build_library \\
        --out plugins/hapticframe_mpm_sand/data/response-library.npz

runs the engine once per depth in free sand and once per (depth, object radius, lateral
offset) towards a buried cylinder, and stores the forces as ratios of the free drag (see
:mod:`hapticframe_mpm_sand._library`). ``--voxel-size-m``, ``--particles-per-cell`` and
``--step-s`` set the resolution; the grid is set by ``--depths-m``, ``--radii-m`` and
``--offsets-u`` (comma-separated). One line of progress per run.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ._engine import EngineSettings, RakeCase, rake
from ._library import ResponseLibrary, material_parameters, save_library

__all__ = ["build_library", "main", "object_case", "smooth"]

#: Plate front's travel in every run, and where the object's leading point sits ahead of the
#: start; the s grid spans that approach at the grid's spacing.
TRAVEL_M = 0.055
S_SPACING_M = 0.0025
PLATE_HALF_WIDTH_M = 0.01


def smooth(values: NDArray[np.float64], window: int) -> NDArray[np.float64]:
    """Centred moving average over ``window`` samples (shorter at the ends): removes the
    engine's fluctuation at the grid's cell size, which is no property of the sand."""
    v = np.asarray(values, dtype=np.float64)
    if window <= 1 or v.size == 0:
        return v.copy()
    kernel = np.ones(window)
    total = np.convolve(v, kernel, mode="same")
    count = np.convolve(np.ones_like(v), kernel, mode="same")
    return np.asarray(total / count, dtype=np.float64)


def object_case(depth_m: float, radius_m: float, offset_u: float) -> RakeCase:
    """The run towards a cylinder of ``radius_m`` whose leading point is TRAVEL_M ahead."""
    start = RakeCase().start_x_m
    return RakeCase(
        depth_m=depth_m, travel_m=TRAVEL_M, object_radius_m=radius_m,
        object_x_m=start + TRAVEL_M + radius_m,
        lateral_offset_m=offset_u * (radius_m + PLATE_HALF_WIDTH_M),
    )


def build_library(
    depths_m: Sequence[float],
    radii_m: Sequence[float],
    offsets_u: Sequence[float],
    settings: EngineSettings,
    progress: Callable[[str], None] = print,
    seed: int = 0,
) -> ResponseLibrary:
    """Run the engine on the grid and return the library (CPU time in ``settings[-1]``)."""
    start_cpu = time.process_time()
    window = max(1, round(settings.voxel_size_m / (RakeCase().speed_m_per_s * settings.step_s)))
    s_grid = np.arange(-TRAVEL_M + S_SPACING_M, 1e-12, S_SPACING_M)
    free_rows = []
    travel = None
    shape = (len(depths_m), len(radii_m), len(offsets_u), s_grid.size)
    ratio_x, ratio_y = np.ones(shape), np.zeros(shape)
    for i, depth in enumerate(depths_m):
        free = rake(RakeCase(depth_m=depth, travel_m=TRAVEL_M), settings, seed=seed)
        travelled = free.x_m - free.x_m[0] + RakeCase().speed_m_per_s * settings.step_s
        drag = np.maximum(smooth(-free.force_n[:, 0], window), 1e-6)
        travel = travelled if travel is None else travel
        free_rows.append(np.interp(travel, travelled, drag))
        progress(f"free sand, depth {depth * 100:.1f} cm: {free.particle_count} particles, "
                 f"steady drag {drag[drag.size // 2:].mean():.3f} N ({free.cpu_s:.1f} s CPU)")
        for j, radius in enumerate(radii_m):
            for k, offset in enumerate(offsets_u):
                run = rake(object_case(depth, radius, offset), settings, seed=seed)
                s = run.x_m - (RakeCase().start_x_m + TRAVEL_M)
                fx = smooth(-run.force_n[:, 0], window)
                fy = smooth(-run.force_n[:, 1], window)
                ratio_x[i, j, k] = np.interp(s_grid, s, fx / drag)
                ratio_y[i, j, k] = np.interp(s_grid, s, fy / drag)
                progress(f"  object r {radius * 100:.1f} cm, offset u {offset:.2f}: ratio at "
                         f"1 cm {np.interp(-0.01, s, fx / drag):.2f} ({run.cpu_s:.1f} s CPU)")
    assert travel is not None
    cfg = settings
    return ResponseLibrary(
        depths_m=np.asarray(depths_m, dtype=np.float64),
        radii_m=np.asarray(radii_m, dtype=np.float64),
        offsets_u=np.asarray(offsets_u, dtype=np.float64),
        s_m=s_grid, travel_m=np.asarray(travel, dtype=np.float64),
        free_drag_n=np.vstack(free_rows), ratio_x=ratio_x, ratio_y=ratio_y,
        settings=np.array([cfg.voxel_size_m, cfg.particles_per_cell, cfg.step_s,
                           cfg.max_iterations, cfg.friction_coefficient, cfg.dilatancy,
                           cfg.bulk_density_kg_per_m3,
                           RakeCase().speed_m_per_s, time.process_time() - start_cpu]),
    )


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",") if v.strip()]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hapticframe_mpm_sand.build_library",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--depths-m", type=_floats, default=[0.02, 0.03, 0.044])
    parser.add_argument("--radii-m", type=_floats, default=[0.015, 0.03])
    parser.add_argument("--offsets-u", type=_floats, default=[0.0, 0.5, 1.0])
    parser.add_argument("--voxel-size-m", type=float, default=EngineSettings.voxel_size_m)
    parser.add_argument("--particles-per-cell", type=float,
                        default=EngineSettings.particles_per_cell)
    parser.add_argument("--step-s", type=float, default=EngineSettings.step_s)
    parser.add_argument("--friction-angle-deg", type=float, default=42.0)
    parser.add_argument("--dilation-angle-deg", type=float, default=12.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    friction, dilatancy = material_parameters(args.friction_angle_deg, args.dilation_angle_deg)
    settings = EngineSettings(voxel_size_m=args.voxel_size_m,
                              particles_per_cell=args.particles_per_cell, step_s=args.step_s,
                              friction_coefficient=friction, dilatancy=dilatancy)
    try:
        library = build_library(args.depths_m, args.radii_m, args.offsets_u, settings,
                                progress=lambda line: print(line, flush=True), seed=args.seed)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    save_library(args.out, library)
    c, n = library.drag_law
    print(f"wrote {args.out}: drag = {c:.4g} d^{n:.2f} N, {library.settings[-1]:.0f} s CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
