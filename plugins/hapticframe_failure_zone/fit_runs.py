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

from hapticframe import atomic_write, read_calibration_run
from hapticframe.kinds import BuildContext

from ._calibration import FailureZoneFit
from ._config import FailureZoneConfig
from ._kernel import FailureZoneKernel

__all__ = ["fit_recorded_runs", "main"]


def fit_recorded_runs(run_dirs: Sequence[str | Path], robot: str = "arm",
                      rake_angle_deg: float = 90.0) -> FailureZoneFit:
    """:func:`fit_failure_zone` over recorded runs (movement indices kept apart per run).

    A thin wrapper over the train step: each run is read with
    :func:`hapticframe.read_calibration_run` and the recordings go to
    :meth:`FailureZoneKernel.fit <hapticframe_failure_zone.FailureZoneKernel.fit>`, the
    sensor model's own fit step.

    Raises
    ------
    ValueError
        Naming the run and file that is missing or lacks an array.
    """
    if not run_dirs:
        raise ValueError("no recorded runs given")
    recordings = [read_calibration_run(run_dir, robot) for run_dir in run_dirs]
    kernel = FailureZoneKernel(FailureZoneConfig(rake_angle_deg=rake_angle_deg),
                               BuildContext(id="failure-zone-fit",
                                            rng=np.random.default_rng(0)))
    kernel.fit(recordings)
    assert kernel._fit is not None  # set by fit
    return kernel._fit


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
