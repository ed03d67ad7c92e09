"""Rebuild the learned zone's bundled model (plugins/hapticframe_learned_zone/data/sandbox.json).

The calibration procedure of docs/calibration.md in the analytic sandbox: three searches
recorded with ``run.halt_on_interaction: false`` over objects buried where we know them
(none of them a placement any benchmark scores), the drag-ratio classifier's reports
counted by :func:`hapticframe_learned_zone.fit_counts`. From the repository's root::

    python tests/data/learned_zone/build_bundled.py [--out DIR]

About 10 s on one core. The recordings go to ``DIR`` (default: a temporary folder).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from hapticframe import read_calibration_run
from hapticframe_learned_zone import LearnedZoneConfig, fit_counts

ROOT = Path(__file__).resolve().parents[3]
TARGET = ROOT / "plugins" / "hapticframe_learned_zone" / "data" / "sandbox.json"
#: Known objects of the calibration runs (map frame of the 0.75 x 0.5 m sandbox).
OBJECTS = (
    "{shape: circle, center_m: [0.25, 0.32], radius_m: 0.03}",
    "{shape: ellipse, center_m: [0.55, 0.30], semi_axes_m: [0.045, 0.025], orientation_deg: 100}",
    "{shape: circle, center_m: [0.40, 0.18], radius_m: 0.04}",
)
MOVEMENTS = 12


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="learned-zone-"))
    runs = []
    for i, obj in enumerate(OBJECTS):
        run_dir = out / f"calibration-{i}"
        subprocess.run(
            [sys.executable, "-m", "hapticframe", "run",
             str(ROOT / "examples" / "search-ellipse-physics-drag.yaml"), "--out", str(run_dir),
             "--overwrite", "--quiet", "--set", "robots[0].type=sandbox",
             "--set", "run.halt_on_interaction=false", "--set", f"run.max_movements={MOVEMENTS}",
             "--set", "run.figures=false", "--set", "run.record=false",
             "--set", f"seed={100 + i}", "--set", f"scene.objects=[{obj}]"],
            check=True)
        runs.append(run_dir)
    recordings = [read_calibration_run(r, "arm", "jamming") for r in runs]
    model, report = fit_counts(recordings, LearnedZoneConfig())
    report["recordings"] = [f"analytic sandbox, drag-ratio-jamming defaults, {MOVEMENTS} "
                            f"movements over {obj}" for obj in OBJECTS]
    model["report"] = report
    TARGET.write_text(json.dumps(model, separators=(",", ":")) + "\n")
    print(f"{TARGET}: {report['samples_counted']} samples counted, "
          f"{report['samples_with_object_in_grid']} with the object in the grid")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
