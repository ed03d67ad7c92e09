"""A response library against direct engine runs it was not built from (issue 32, §4).

::

    OMP_NUM_THREADS=1 nice -n 10 python -m hapticframe_mpm_sand.held_out \\
        --library plugins/hapticframe_mpm_sand/data/response-library.npz --out DIR --workers 2

runs, at the library's own engine settings (cell size, step, iterations, sand: read from the
file) but another seed, the engine at configurations off the library's grid — cylinders
between its depths, radii and offsets and, where it has shape tables, each shape at yaws and
signed offsets between its grid's — and compares the library's force with the run's
(:func:`hapticframe_mpm_sand._checks.held_out_error`). Writes ``held-out.json`` and
``held-out.md``. Needs the ``physics`` extra.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import json
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import atomic_write

from ._checks import HeldOutError, held_out_error
from ._engine import EngineSettings
from ._library import ResponseLibrary, load_library
from .build_library import ShapeSpec

__all__ = ["default_configurations", "main", "run_held_out", "settings_of", "spec_of"]

#: (depth, radius, offset u) of cylinders and (depth, yaw, signed u) of shapes, all off the
#: bundled grids (depths 2/3/4.4 cm, yaws 0/45/90 degrees, offsets 0/0.75/1.5 ...).
CYLINDER_CASES = ((0.035, 0.025, 0.4), (0.025, 0.03, 1.1))
SHAPE_CASES = ((0.035, 30.0, 0.4), (0.025, 70.0, -0.5))


def settings_of(library: ResponseLibrary) -> EngineSettings:
    """The engine settings a library was built with (from its ``settings`` array)."""
    voxel, per_cell, step, iterations, friction, dilatancy, density = library.settings[:7]
    return EngineSettings(voxel_size_m=float(voxel), particles_per_cell=float(per_cell),
                          step_s=float(step), max_iterations=int(iterations),
                          friction_coefficient=float(friction), dilatancy=float(dilatancy),
                          bulk_density_kg_per_m3=float(density))


def spec_of(outline_m: NDArray[np.float64]) -> ShapeSpec:
    """The ellipse or box whose outline (about its centre, at yaw 0) ``outline_m`` is: a box
    has points at its corners, an ellipse has none there."""
    points = np.asarray(outline_m, dtype=np.float64)
    a, b = float(np.abs(points[:, 0]).max()), float(np.abs(points[:, 1]).max())
    corner = np.min(np.hypot(np.abs(points[:, 0]) - a, np.abs(points[:, 1]) - b))
    return ShapeSpec("box" if corner < 0.05 * min(a, b) else "ellipse", (a, b))


def default_configurations(library: ResponseLibrary) -> list[dict[str, Any]]:
    """The held-out configurations for ``library``: the cylinders, and each of its shapes."""
    configs: list[dict[str, Any]] = [
        {"depth_m": d, "radius_m": r, "offset_u": u} for d, r, u in CYLINDER_CASES]
    for index in range(library.shape_count):
        spec = spec_of(library.shape_outlines_m[index])
        configs += [{"depth_m": d, "radius_m": 0.0, "offset_u": u, "shape_index": index,
                     "shape": spec, "yaw_deg": yaw} for d, yaw, u in SHAPE_CASES]
    return configs


def _one(job: tuple[Path, dict[str, Any], int]) -> HeldOutError:
    path, config, seed = job
    library = load_library(path)
    return held_out_error(library, settings_of(library), seed=seed, **config)


def run_held_out(library_path: Path, configs: Sequence[dict[str, Any]], workers: int = 1,
                 seed: int = 1, progress: Callable[[str], None] = print,
                 ) -> list[HeldOutError]:
    """Every configuration's error, ``workers`` engine processes at a time."""
    jobs = [(library_path, dict(config), seed) for config in configs]
    results: list[HeldOutError] = []
    if workers <= 1:
        outcomes: Any = map(_one, jobs)
        for result in outcomes:
            results.append(result)
            progress(_line(result, len(results), len(jobs)))
        return results
    # Spawned, not forked: Warp's runtime must not be shared between processes.
    with concurrent.futures.ProcessPoolExecutor(
            workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        for result in pool.map(_one, jobs):
            results.append(result)
            progress(_line(result, len(results), len(jobs)))
    return results


def _label(row: HeldOutError) -> str:
    if row.shape < 0:
        return (f"cylinder r {row.radius_m * 100:g} cm, depth {row.depth_m * 100:g} cm, "
                f"u {row.offset_u:g}")
    return (f"shape {row.shape}, yaw {row.yaw_deg:g} deg, depth {row.depth_m * 100:g} cm, "
            f"u {row.offset_u:+g}")


def _line(row: HeldOutError, done: int, total: int) -> str:
    return (f"[{done}/{total}] {_label(row)}: force RMS {100 * row.rms_relative:.1f} % of free "
            f"drag, ratio RMS {row.ratio_rms:.2f} ({row.cpu_s:.0f} s CPU)")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hapticframe_mpm_sand.held_out",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--library", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--seed", type=int, default=1,
                        help="the runs' particle jitter (the bundled libraries: seed 0)")
    args = parser.parse_args(argv)
    from ._engine import engine_available

    if not engine_available():
        print("error: held-out runs need the engine: pip install 'hapticframe[physics]'",
              file=sys.stderr)
        return 2
    try:
        library = load_library(args.library)
    except ValueError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    configs = default_configurations(library)
    load = os.getloadavg()
    start = time.perf_counter()
    rows = run_held_out(args.library, configs, max(1, args.workers), args.seed,
                        progress=lambda line: print(line, flush=True))
    args.out.mkdir(parents=True, exist_ok=True)
    record = {"library": str(args.library), "settings": dataclasses.asdict(settings_of(library)),
              "seed": args.seed, "wall_s": time.perf_counter() - start,
              "load_average_at_start": list(load), "load_average_at_end": list(os.getloadavg()),
              "rows": [dataclasses.asdict(row) for row in rows]}
    atomic_write(args.out / "held-out.json", json.dumps(record, indent=2) + "\n")
    table = ["| held out | force RMS / free drag | ratio RMS | ratio at 1 cm: direct / library |",
             "|---|---|---|---|"]
    table += [f"| {_label(row)} | {100 * row.rms_relative:.1f} % | {row.ratio_rms:.2f} | "
              f"{row.direct_ratio_at_1cm:.2f} / {row.library_ratio_at_1cm:.2f} |" for row in rows]
    atomic_write(args.out / "held-out.md", "\n".join(table) + "\n")
    print(f"wrote {args.out / 'held-out.json'} and held-out.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
