"""Resolution convergence of the engine's rake ahead of a buried cylinder (issue 32, §4).

::

    OMP_NUM_THREADS=1 nice -n 5 python -m hapticframe_mpm_sand.convergence --out DIR

runs, at each cell size (``--voxel-sizes-m``, default 10, 7.5, 5 and 3.75 mm), the engine
once in free sand and once towards a cylinder of ``--radius-m`` dead ahead of the plate
(offset 0) at ``--depth-m``, with the library's material (φ, ψ from ``--friction-angle-deg``
and ``--dilation-angle-deg``), step and particles per cell, and measures what the bench's
rise check measures (:mod:`hapticframe_mpm_sand._checks`): the steady free drag, the force
ratio's onset distance (where the ratio to free drag first stays ≥ 1.1 before the leading
point) and the ratio at 2 and 1 cm. The bench looks for the onset only after half the travel,
which caps it at 2.5 cm; the study also looks for it after ``--startup-m`` of travel (1 cm).
Writes ``convergence.json`` (every number, and the ratio and free-drag profiles) and
``convergence.png`` (the ratio against distance to the object, and the free drag against
travel, one line per cell size). One line of progress per cell size. Needs the ``physics``
extra; the figure needs matplotlib.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import atomic_write

from ._checks import onset_distance, rise_profile
from ._engine import EngineSettings, RakeCase, RakeResult
from ._library import material_parameters
from .build_library import TRAVEL_M, object_case

__all__ = ["ConvergenceRow", "convergence_study", "main", "save_figure", "write_results"]

#: The study's cell sizes (m): the 10 mm and 7.5 mm libraries, the bench's 5 mm, and finer.
DEFAULT_VOXEL_SIZES_M = (0.01, 0.0075, 0.005, 0.00375)

#: Travel after which :attr:`ConvergenceRow.onset_after_startup_m` looks for the onset.
DEFAULT_STARTUP_M = 0.01

RakeFunction = Callable[[RakeCase, EngineSettings, int], RakeResult]


@dataclasses.dataclass(frozen=True)
class ConvergenceRow:
    """One cell size: the rise check's measures, the cost, and the profiles behind them."""

    voxel_size_m: float
    #: Particles of the run towards the object (the free run has a few more).
    particles: int
    free_particles: int
    steps: int
    #: Steady free drag: mean of the smoothed free drag over the last half of the travel.
    free_drag_n: float
    #: The bench's onset (``_checks.onset_distance``: looked for only after half the
    #: travel) and the farthest it can see; equal means the onset lies farther out.
    onset_distance_m: float
    onset_limit_m: float
    #: The onset looked for after only ``startup_m`` of travel (the ratio compares runs at
    #: the same travel, so the free drag's slow rise cancels), and the farthest it can see.
    startup_m: float
    onset_after_startup_m: float
    onset_after_startup_limit_m: float
    ratio_at_2cm: float
    ratio_at_1cm: float
    #: CPU and wall time of both runs' stepping (kernel compilation and set-up excluded).
    cpu_s: float
    wall_s: float
    #: Wall time of both runs from building the model to the last step.
    total_wall_s: float
    #: Per step of the run towards the object: the plate front relative to the leading
    #: point (m) and the smoothed force ratio; per step of the free run: travel (m) and the
    #: smoothed free drag (N).
    s_m: tuple[float, ...]
    ratio: tuple[float, ...]
    travel_m: tuple[float, ...]
    free_drag_profile_n: tuple[float, ...]


def _onset_limit(s: NDArray[np.float64], startup_m: float) -> float:
    """The farthest onset :func:`onset_distance` can report after ``startup_m`` (m)."""
    looked = s[s >= s[0] + startup_m]
    return float(-looked[0]) if looked.size else 0.0


def _default_rake(case: RakeCase, settings: EngineSettings, seed: int) -> RakeResult:
    from ._engine import rake

    return rake(case, settings, seed=seed)


def convergence_study(
    voxel_sizes_m: Sequence[float],
    base: EngineSettings,
    depth_m: float = 0.044,
    radius_m: float = 0.03,
    seed: int = 0,
    startup_m: float = DEFAULT_STARTUP_M,
    rake_fn: RakeFunction = _default_rake,
    progress: Callable[[str], None] = print,
) -> list[ConvergenceRow]:
    """Run the free and the object run at each cell size (``base`` gives everything else);
    the second onset is looked for after ``startup_m`` of travel."""
    rows = []
    for voxel in voxel_sizes_m:
        settings = dataclasses.replace(base, voxel_size_m=float(voxel))
        start = time.perf_counter()
        free = rake_fn(RakeCase(depth_m=depth_m, travel_m=TRAVEL_M), settings, seed)
        case = object_case(depth_m, radius_m, 0.0)
        run = rake_fn(case, settings, seed)
        total_wall = time.perf_counter() - start
        s, ratio, free_drag = rise_profile(free, run, case, settings)
        travel = free.x_m - free.x_m[0] + case.speed_m_per_s * settings.step_s
        steady = float(free_drag[free_drag.size // 2:].mean())
        row = ConvergenceRow(
            voxel_size_m=float(voxel), particles=run.particle_count,
            free_particles=free.particle_count, steps=int(s.size),
            free_drag_n=steady,
            onset_distance_m=onset_distance(s, ratio),
            onset_limit_m=_onset_limit(s, TRAVEL_M / 2),
            startup_m=startup_m,
            onset_after_startup_m=onset_distance(s, ratio, startup_m=startup_m),
            onset_after_startup_limit_m=_onset_limit(s, startup_m),
            ratio_at_2cm=float(np.interp(-0.02, s, ratio)),
            ratio_at_1cm=float(np.interp(-0.01, s, ratio)),
            cpu_s=free.cpu_s + run.cpu_s, wall_s=free.wall_s + run.wall_s,
            total_wall_s=total_wall,
            s_m=tuple(float(v) for v in s), ratio=tuple(float(v) for v in ratio),
            travel_m=tuple(float(v) for v in travel),
            free_drag_profile_n=tuple(float(v) for v in free_drag),
        )
        rows.append(row)
        progress(f"{voxel * 1000:g} mm cells: {row.particles} particles, free drag "
                 f"{row.free_drag_n:.3f} N, >= 1.1 from {row.onset_distance_m * 100:.2f} cm "
                 f"(limit {row.onset_limit_m * 100:.2f}; after the start-up "
                 f"{row.onset_after_startup_m * 100:.2f}, limit "
                 f"{row.onset_after_startup_limit_m * 100:.2f} cm), "
                 f"x{row.ratio_at_2cm:.2f} at 2 cm, x{row.ratio_at_1cm:.2f} at 1 cm "
                 f"({row.cpu_s:.1f} s CPU, {row.total_wall_s:.1f} s wall)")
    return rows


def save_figure(rows: Sequence[ConvergenceRow], path: Path, depth_m: float,
                radius_m: float) -> Path:
    """The ratio against distance to the leading point, and the free drag against travel."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    for i, row in enumerate(rows):
        label = f"{row.voxel_size_m * 1000:g} mm cells ({row.particles} particles)"
        distance_cm = -100 * np.asarray(row.s_m)
        (line,) = left.plot(distance_cm, row.ratio, label=label)
        if row.onset_after_startup_m > 0:
            # Shrinking markers: equal onsets stay visible one inside the other.
            left.plot([100 * row.onset_after_startup_m], [1.1], "o", color=line.get_color(),
                      markersize=max(3.0, 10.0 - 2.0 * i), zorder=3 + i)
        right.plot(100 * np.asarray(row.travel_m), row.free_drag_profile_n,
                   color=line.get_color(), label=label)
    left.axhline(1.1, color="0.5", linestyle="--", linewidth=1.0, label="1.1 × free drag")
    left.axvspan(0.0, 100 * 0.005, color="0.9", label="last 5 mm (not measured)")
    if rows:
        left.axvline(100 * rows[0].onset_limit_m, color="0.3", linestyle=":", linewidth=1.0,
                     label="the bench's onset looks only nearer than this")
    left.invert_xaxis()
    left.set_xlabel("distance from plate front to the cylinder's leading point (cm)")
    left.set_ylabel("force / free drag at the same travel (1)")
    left.set_title(f"towards a {radius_m * 100:g} cm cylinder, {depth_m * 100:g} cm deep "
                   "(dots: onset)")
    left.legend(fontsize=8)
    right.axvspan(0.0, 100 * TRAVEL_M / 2, color="0.93",
                  label="first half: not in the steady mean")
    right.set_xlabel("plate travel (cm)")
    right.set_ylabel("free drag, smoothed (N)")
    right.set_title(f"free sand, {depth_m * 100:g} cm deep")
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def write_results(out: Path, rows: Sequence[ConvergenceRow], meta: dict[str, Any]) -> Path:
    """Write ``convergence.json`` (``meta`` and every row) into ``out``; returns its path."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / "convergence.json"
    atomic_write(path, json.dumps({**meta, "rows": [dataclasses.asdict(r) for r in rows]},
                                  indent=2, allow_nan=False) + "\n")
    return path


def _floats(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}"
                                         ) from error
    if not values or not all(math.isfinite(v) and 0 < v <= 0.1 for v in values):
        raise argparse.ArgumentTypeError(f"cell sizes must be in (0, 0.1] m: {text!r}")
    return values


def _length(text: str) -> float:
    try:
        value = float(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from error
    if not (math.isfinite(value) and 0 < value <= 0.1):
        raise argparse.ArgumentTypeError(f"must be in (0, 0.1] m: {text!r}")
    return value


def _iterations(text: str) -> int:
    try:
        value = int(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from error
    if not 1 <= value <= 100_000:
        raise argparse.ArgumentTypeError(f"must be in [1, 100000]: {text!r}")
    return value


def main(argv: Sequence[str] | None = None,
         rake_fn: RakeFunction = _default_rake) -> int:
    parser = argparse.ArgumentParser(prog="python -m hapticframe_mpm_sand.convergence",
                                     description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--voxel-sizes-m", type=_floats, default=list(DEFAULT_VOXEL_SIZES_M))
    parser.add_argument("--depth-m", type=_length, default=0.044)
    parser.add_argument("--radius-m", type=_length, default=0.03)
    parser.add_argument("--step-s", type=_length, default=EngineSettings.step_s)
    parser.add_argument("--friction-angle-deg", type=float, default=42.0)
    parser.add_argument("--dilation-angle-deg", type=float, default=12.0)
    parser.add_argument("--startup-m", type=_length, default=DEFAULT_STARTUP_M,
                        help="travel after which the second onset is looked for (m)")
    parser.add_argument("--max-iterations", type=_iterations,
                        default=EngineSettings.max_iterations,
                        help="the solver's iteration cap per step (the library's: 200; "
                        "docs/physics-world.md: no run is converged in it)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if not (0 < args.friction_angle_deg < 90 and 0 <= args.dilation_angle_deg
            <= args.friction_angle_deg):
        parser.error("need 0 < --friction-angle-deg < 90 and 0 <= --dilation-angle-deg <= "
                     "--friction-angle-deg")
    if rake_fn is _default_rake:
        from ._engine import engine_available

        if not engine_available():
            print("error: the convergence study runs the engine: pip install "
                  "'hapticframe[physics]'", file=sys.stderr)
            return 2
    friction, dilatancy = material_parameters(args.friction_angle_deg, args.dilation_angle_deg)
    base = EngineSettings(step_s=args.step_s, friction_coefficient=friction,
                          dilatancy=dilatancy, max_iterations=args.max_iterations)
    load = os.getloadavg()
    rows = convergence_study(args.voxel_sizes_m, base, depth_m=args.depth_m,
                             radius_m=args.radius_m, seed=args.seed,
                             startup_m=args.startup_m, rake_fn=rake_fn,
                             progress=lambda line: print(line, flush=True))
    meta = {
        "depth_m": args.depth_m, "radius_m": args.radius_m, "lateral_offset_m": 0.0,
        "friction_angle_deg": args.friction_angle_deg,
        "dilation_angle_deg": args.dilation_angle_deg, "step_s": base.step_s,
        "particles_per_cell": base.particles_per_cell, "travel_m": TRAVEL_M,
        "seed": args.seed, "onset_ratio": 1.1, "startup_m": args.startup_m,
        "max_iterations": base.max_iterations,
        "load_average_at_start": list(load), "load_average_at_end": list(os.getloadavg()),
        "cpu_count": os.cpu_count(), "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
    }
    path = write_results(args.out, rows, meta)
    figure = save_figure(rows, args.out / "convergence.png", args.depth_m, args.radius_m)
    print(f"wrote {path} and {figure}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
