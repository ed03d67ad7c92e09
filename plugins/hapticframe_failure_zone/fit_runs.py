"""Fit the failure-zone kernel's parameters from recorded runs (issue 29 §2).

::

    python -m hapticframe_failure_zone.fit_runs runs/recorded-physics [more runs] \\
        --out runs/failure-zone-fit.json

reads each run's ``trace.npz`` (the robot's position and heading), ``ground_truth.npz``
(depth, movement and the world's states) and ``run.json`` (the scene's buried objects),
fits :func:`~hapticframe_failure_zone.fit_failure_zone` over all of them and writes the fit
with the config fields it sets (``config``) as JSON. Record with ``run.halt_on_interaction:
false`` so that movements run on through jamming. Exit 0 ok, 1 nothing to fit, 2 bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hapticframe import Scene, atomic_write

from ._calibration import FailureZoneFit, fit_failure_zone

__all__ = ["fit_recorded_runs", "main"]


def fit_recorded_runs(run_dirs: Sequence[str | Path], robot: str = "arm",
                      rake_angle_deg: float = 90.0) -> FailureZoneFit:
    """:func:`fit_failure_zone` over recorded runs (movement indices kept apart per run).

    Raises
    ------
    ValueError
        Naming the run and file that is missing or lacks an array.
    """
    if not run_dirs:
        raise ValueError("no recorded runs given")
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("p", "h", "d", "m", "s")}
    outlines: list[np.ndarray] = []
    base = 0
    for run_dir in map(Path, run_dirs):
        try:
            with np.load(run_dir / "trace.npz", allow_pickle=False) as trace:
                parts["p"].append(trace[f"robot/{robot}/position_m"])
                parts["h"].append(trace[f"robot/{robot}/heading_rad"])
            with np.load(run_dir / "ground_truth.npz", allow_pickle=False) as truth:
                parts["d"].append(truth["depth_m"])
                parts["s"].append(truth["state"])
                movement = truth["movement_index"].astype(np.int64)
            scene = json.loads((run_dir / "run.json").read_text())["resolved_config"]["scene"]
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"{run_dir}: not a recorded run with ground truth "
                             f"({type(exc).__name__}: {exc})") from exc
        if scene is None:
            raise ValueError(f"{run_dir}/run.json: the run has no scene (no buried objects)")
        parts["m"].append(movement + base)
        base += int(movement.max()) + 1 if movement.size else 0
        outlines.extend(o.outline() for o in Scene.model_validate(scene).objects)
    p, h, d, m, s = (np.concatenate(parts[k]) for k in ("p", "h", "d", "m", "s"))
    return fit_failure_zone(p, h, d, m, s, outlines, rake_angle_deg=rake_angle_deg)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m hapticframe_failure_zone.fit_runs",
                                     description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, help="recorded run directories")
    parser.add_argument("--out", type=Path, required=True, help="the fit, as JSON")
    parser.add_argument("--robot", default="arm", help="the recorded robot's id")
    parser.add_argument("--rake-angle-deg", type=float, default=90.0)
    args = parser.parse_args(argv)
    try:
        fit = fit_recorded_runs(args.runs, args.robot, args.rake_angle_deg)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1 if "no movement became jammed" in str(exc) else 2
    atomic_write(args.out, json.dumps(fit.as_dict(), indent=2) + "\n")
    print(f"rupture distance {fit.rupture_ratio:.3f} x depth (shear-band angle "
          f"{fit.shear_band_angle_deg:.1f} deg), sector half-angle "
          f"{fit.sector_half_angle_deg:.1f} deg, depth {100 * fit.initial_depth_m:.2f} cm "
          f"- {100 * fit.depth_decrement_m:.2f} cm x {fit.depth_decrement_ratio:.2f}^k; "
          f"{len(fit.onset_distance_m)} onsets: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
