"""Build the response library from engine runs (needs the ``physics`` extra).

::

    OMP_NUM_THREADS=1 nice -n 10 python -m hapticframe_mpm_sand.build_library \\
        --shape ellipse:0.045,0.025 --shape box:0.035,0.025 --workers 2 \\
        --out plugins/hapticframe_mpm_sand/data/response-library.npz

runs the engine once per depth in free sand, once per (depth, object radius, lateral
offset) towards a buried cylinder and, for each ``--shape``, once per (depth, yaw, signed
offset) towards that elliptic or rectangular prism, and stores the forces as ratios of the
free drag (see :mod:`hapticframe_mpm_sand._library`). ``--voxel-size-m``,
``--particles-per-cell``, ``--step-s`` and ``--max-iterations`` set the resolution (the
defaults are the bundled library's: 7.5 mm cells, 7.5 ms steps, 200 iterations; see
docs/physics-world.md for why the step, not the cell, got the CPU); the grid is set by
``--depths-m``, ``--radii-m``, ``--offsets-u``, ``--yaws-deg``, ``--shape-offsets-u`` and
``--travel-m`` (comma-separated lists). ``--workers`` runs that many engine processes.
One line of progress per run.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import multiprocessing
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ._engine import EngineSettings, RakeCase, RakeResult, object_footprint, rake
from ._library import ResponseLibrary, material_parameters, save_library

__all__ = ["ShapeSpec", "build_library", "main", "object_case", "parse_shape", "shape_case",
           "smooth"]

#: Plate front's travel in every run, and where the object's leading point sits ahead of the
#: start; the s grid spans that approach at the grid's spacing.
TRAVEL_M = 0.055
S_SPACING_M = 0.0025
PLATE_HALF_WIDTH_M = 0.01
#: The bundled library's step and approach (the checks and the convergence study keep
#: EngineSettings' 30 ms and TRAVEL_M, which their documented tables were measured at).
LIBRARY_STEP_S = 0.0075
LIBRARY_TRAVEL_M = 0.075


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


def object_case(depth_m: float, radius_m: float, offset_u: float,
                travel_m: float = TRAVEL_M) -> RakeCase:
    """The run towards a cylinder of ``radius_m`` whose leading point is ``travel_m`` ahead."""
    start = RakeCase().start_x_m
    return RakeCase(
        depth_m=depth_m, travel_m=travel_m, object_radius_m=radius_m,
        object_x_m=start + travel_m + radius_m,
        lateral_offset_m=offset_u * (radius_m + PLATE_HALF_WIDTH_M),
    )


@dataclasses.dataclass(frozen=True)
class ShapeSpec:
    """A shape the library holds tables for: ``kind`` "ellipse" (semi-axes) or "box"
    (half-sides), ``half_extents_m`` along its own x and y."""

    kind: str
    half_extents_m: tuple[float, float]

    def outline(self, points: int = 64) -> NDArray[np.float64]:
        """Its outline about its centre at yaw 0 (``points`` points; a box's perimeter
        sampled evenly, corners included)."""
        case = RakeCase(object_shape=self.kind, object_half_extents_m=self.half_extents_m)
        corners = object_footprint(case, points)
        if self.kind == "ellipse":
            return corners
        closed = np.vstack([corners, corners[:1]])
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0),
                                                               axis=1))])
        t = np.linspace(0, arc[-1], points, endpoint=False)
        return np.column_stack([np.interp(t, arc, closed[:, 0]),
                                np.interp(t, arc, closed[:, 1])])


def parse_shape(text: str) -> ShapeSpec:
    """``kind:a,b`` (metres), e.g. ``ellipse:0.035,0.025`` or ``box:0.035,0.025``."""
    kind, _, sizes = text.partition(":")
    values = _floats(sizes) if sizes else []
    if kind not in ("ellipse", "box") or len(values) != 2 or min(values) <= 0:
        raise ValueError(f"shape {text!r}: give kind:a,b with kind ellipse or box and two "
                         "positive half-extents in metres (e.g. ellipse:0.035,0.025)")
    return ShapeSpec(kind, (values[0], values[1]))


def shape_case(depth_m: float, shape: ShapeSpec, yaw_deg: float, offset_u: float,
               travel_m: float = TRAVEL_M) -> RakeCase:
    """The run towards ``shape`` at ``yaw_deg`` whose foremost point is ``travel_m`` ahead and
    whose across-heading extent is centred ``offset_u`` (>= 0) half-widths to the left
    (half-width: the object's half-extent across the heading plus the plate's)."""
    if offset_u < 0:
        raise ValueError("shape_case takes offsets >= 0 (the right side is the mirror)")
    probe = RakeCase(object_shape=shape.kind, object_half_extents_m=shape.half_extents_m,
                     object_yaw_deg=yaw_deg)
    footprint = object_footprint(probe)
    across_low, across_high = float(footprint[:, 1].min()), float(footprint[:, 1].max())
    half_across = (across_high - across_low) / 2
    start = RakeCase().start_x_m
    return dataclasses.replace(
        probe, depth_m=depth_m, travel_m=travel_m,
        object_x_m=start + travel_m - float(footprint[:, 0].min()),
        lateral_offset_m=offset_u * (half_across + PLATE_HALF_WIDTH_M)
        - (across_low + across_high) / 2,
    )


def _signed_offsets(offsets_u: Sequence[float]) -> NDArray[np.float64]:
    magnitudes = sorted({abs(float(u)) for u in offsets_u})
    # + 0.0: no -0.0 on the grid.
    return np.asarray(sorted({-u for u in magnitudes} | set(magnitudes)), dtype=np.float64) + 0.0


def _rake_job(job: tuple[str, RakeCase, EngineSettings, int]) -> tuple[str, RakeResult]:
    """One engine run in a worker process (top level: the pool pickles it)."""
    key, case, settings, seed = job
    return key, rake(case, settings, seed=seed)


def _run_all(jobs: list[tuple[str, RakeCase, EngineSettings, int]], workers: int,
             progress: Callable[[str], None]) -> dict[str, RakeResult]:
    """Every job's result by key, ``workers`` engine processes at a time, a line per run."""
    results: dict[str, RakeResult] = {}

    def report(key: str, result: RakeResult) -> None:
        results[key] = result
        progress(f"[{len(results)}/{len(jobs)}] {key}: {result.particle_count} particles, "
                 f"{result.cpu_s:.1f} s CPU")

    if workers <= 1:
        for job in jobs:
            report(*_rake_job(job))
        return results
    # Spawned, not forked: Warp's runtime must not be shared between processes.
    with concurrent.futures.ProcessPoolExecutor(
            workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for key, result in pool.map(_rake_job, jobs):
            report(key, result)
    return results


def build_library(
    depths_m: Sequence[float],
    radii_m: Sequence[float],
    offsets_u: Sequence[float],
    settings: EngineSettings,
    progress: Callable[[str], None] = print,
    seed: int = 0,
    shapes: Sequence[ShapeSpec] = (),
    yaws_deg: Sequence[float] = (0.0, 45.0, 90.0),
    shape_offsets_u: Sequence[float] = (0.0, 0.5, 1.0, 1.5),
    workers: int = 1,
    travel_m: float = TRAVEL_M,
) -> ResponseLibrary:
    """Run the engine on the grid and return the library.

    ``shapes`` adds shape tables at ``yaws_deg`` (0–90°) and the offsets ``shape_offsets_u``
    on both sides (the right side run as the mirrored case, except at 0° and 90° where it is
    the mirror of the left). Every run rakes ``travel_m`` up to the object's foremost
    point, so the tables reach that far ahead. The summed CPU time of the runs is
    ``settings[-1]``.
    """
    if not 2 * S_SPACING_M <= travel_m <= 0.5:
        raise ValueError(f"travel_m {travel_m:g}: between {2 * S_SPACING_M:g} and 0.5 m")
    if any(not 0 <= yaw <= 90 for yaw in yaws_deg):
        raise ValueError("shape yaws must lie in 0 ... 90 degrees (the rest are mirrors)")
    window = max(1, round(settings.voxel_size_m / (RakeCase().speed_m_per_s * settings.step_s)))
    s_grid = np.arange(-travel_m + S_SPACING_M, 1e-12, S_SPACING_M)
    signed = _signed_offsets(shape_offsets_u)
    yaws = np.asarray(sorted(set(float(y) for y in yaws_deg)), dtype=np.float64)
    # Every engine run once, by name; every table cell names the run it reads and whether
    # it reads its mirror image (the right side: y reversed).
    cases: dict[str, RakeCase] = {}
    cylinder_cells: list[tuple[tuple[int, int, int], str]] = []
    shape_cells: list[tuple[tuple[int, int, int, int], str, bool]] = []
    for i, depth in enumerate(depths_m):
        cases[f"free d{depth:g}"] = RakeCase(depth_m=depth, travel_m=travel_m)
        for j, radius in enumerate(radii_m):
            for k, offset in enumerate(offsets_u):
                key = f"cylinder d{depth:g} r{radius:g} u{offset:g}"
                cases[key] = object_case(depth, radius, offset, travel_m)
                cylinder_cells.append(((i, j, k), key))
        for n, shape in enumerate(shapes):
            for m, yaw in enumerate(yaws):
                for k, offset in enumerate(signed):
                    mirrored = offset < 0
                    # At 0 and 90 degrees the right side is the left's mirror image; at other
                    # yaws it is run as the mirrored case (yaw and offset negated).
                    run_yaw = yaw if yaw in (0.0, 90.0) or not mirrored else -yaw
                    key = f"shape{n} d{depth:g} yaw{run_yaw:g} u{abs(offset):g}"
                    cases.setdefault(key, shape_case(depth, shape, run_yaw, abs(offset),
                                                     travel_m))
                    shape_cells.append(((i, n, m, k), key, mirrored))
    results = _run_all([(key, case, settings, seed) for key, case in cases.items()],
                       workers, progress)
    free_rows = []
    travel = None
    grid = (len(depths_m), len(radii_m), len(offsets_u), s_grid.size)
    ratio_x, ratio_y = np.ones(grid), np.zeros(grid)
    table = (len(depths_m), len(shapes), yaws.size, signed.size, s_grid.size)
    shape_x, shape_y = np.ones(table), np.zeros(table)
    drags = []
    for depth in depths_m:
        free = results[f"free d{depth:g}"]
        travelled = free.x_m - free.x_m[0] + RakeCase().speed_m_per_s * settings.step_s
        drag = np.maximum(smooth(-free.force_n[:, 0], window), 1e-6)
        travel = travelled if travel is None else travel
        free_rows.append(np.interp(travel, travelled, drag))
        drags.append(drag)

    def ratios(run: RakeResult, drag: NDArray[np.float64]
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        s = run.x_m - (RakeCase().start_x_m + travel_m)
        fx = smooth(-run.force_n[:, 0], window)
        fy = smooth(-run.force_n[:, 1], window)
        return np.interp(s_grid, s, fx / drag), np.interp(s_grid, s, fy / drag)

    for (i, j, k), key in cylinder_cells:
        ratio_x[i, j, k], ratio_y[i, j, k] = ratios(results[key], drags[i])
    for (i, n, m, k), key, mirrored in shape_cells:
        rx, ry = ratios(results[key], drags[i])
        shape_x[i, n, m, k], shape_y[i, n, m, k] = rx, (-ry if mirrored else ry)
    assert travel is not None
    cfg = settings
    cpu = sum(result.cpu_s for result in results.values())
    outlines = (np.stack([spec.outline() for spec in shapes]) if shapes
                else np.zeros((0, 64, 2)))
    return ResponseLibrary(
        depths_m=np.asarray(depths_m, dtype=np.float64),
        radii_m=np.asarray(radii_m, dtype=np.float64),
        offsets_u=np.asarray(offsets_u, dtype=np.float64),
        s_m=s_grid, travel_m=np.asarray(travel, dtype=np.float64),
        free_drag_n=np.vstack(free_rows), ratio_x=ratio_x, ratio_y=ratio_y,
        settings=np.array([cfg.voxel_size_m, cfg.particles_per_cell, cfg.step_s,
                           cfg.max_iterations, cfg.friction_coefficient, cfg.dilatancy,
                           cfg.bulk_density_kg_per_m3, RakeCase().speed_m_per_s, cpu]),
        shape_outlines_m=outlines,
        shape_yaws_deg=yaws if shapes else np.zeros(0),
        shape_offsets_u=signed if shapes else np.zeros(0),
        shape_ratio_x=shape_x if shapes else None,
        shape_ratio_y=shape_y if shapes else None,
    )


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",") if v.strip()]


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hapticframe_mpm_sand.build_library",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--depths-m", type=_floats, default=[0.02, 0.03, 0.044])
    parser.add_argument("--radii-m", type=_floats, default=[0.015, 0.04])
    parser.add_argument("--offsets-u", type=_floats, default=[0.0, 0.75, 1.5, 2.25])
    parser.add_argument("--voxel-size-m", type=float, default=EngineSettings.voxel_size_m)
    parser.add_argument("--particles-per-cell", type=float,
                        default=EngineSettings.particles_per_cell)
    parser.add_argument("--step-s", type=float, default=LIBRARY_STEP_S)
    parser.add_argument("--friction-angle-deg", type=float, default=42.0)
    parser.add_argument("--dilation-angle-deg", type=float, default=12.0)
    parser.add_argument("--max-iterations", type=int, default=EngineSettings.max_iterations,
                        help="the solver's iteration cap per step (docs/physics-world.md: "
                        "the engine is not converged in it)")
    parser.add_argument("--shape", action="append", default=[], metavar="KIND:A,B",
                        help="add tables for a shape: ellipse:a,b (semi-axes) or box:a,b "
                        "(half-sides), metres; repeatable")
    parser.add_argument("--yaws-deg", type=_floats, default=[0.0, 45.0, 90.0])
    parser.add_argument("--shape-offsets-u", type=_floats, default=[0.0, 0.75, 1.5])
    parser.add_argument("--travel-m", type=float, default=LIBRARY_TRAVEL_M,
                        help="each run's approach to the object (the tables' reach ahead)")
    parser.add_argument("--workers", type=int, default=1,
                        help="engine processes at once (each single-threaded)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    friction, dilatancy = material_parameters(args.friction_angle_deg, args.dilation_angle_deg)
    settings = EngineSettings(voxel_size_m=args.voxel_size_m,
                              particles_per_cell=args.particles_per_cell, step_s=args.step_s,
                              max_iterations=args.max_iterations,
                              friction_coefficient=friction, dilatancy=dilatancy)
    start = time.perf_counter()
    try:
        shapes = [parse_shape(text) for text in args.shape]
        library = build_library(args.depths_m, args.radii_m, args.offsets_u, settings,
                                progress=lambda line: print(line, flush=True), seed=args.seed,
                                shapes=shapes, yaws_deg=args.yaws_deg,
                                shape_offsets_u=args.shape_offsets_u,
                                workers=max(1, args.workers), travel_m=args.travel_m)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    save_library(args.out, library)
    law = ""
    if library.depths_m.size >= 2:
        c, n = library.drag_law
        law = f"drag = {c:.4g} d^{n:.2f} N, "
    print(f"wrote {args.out}: {law}{library.settings[-1]:.0f} s CPU "
          f"in the runs, {time.perf_counter() - start:.0f} s wall, "
          f"{args.out.stat().st_size / 1024:.0f} kB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
