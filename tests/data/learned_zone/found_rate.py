"""Found rate of the learned zone beside the failure-zone kernel, in the analytic sandbox
and the mpm-sand world: the calibration procedure of docs/calibration.md, then searches at
the placements of ``bench search`` (seed 0; the calibration circle is at none of them).

    python tests/data/learned_zone/found_rate.py --trials 10 --movements 12 --out /tmp/lz-found

Both searches use drag-ratio-jamming at its defaults and the learned-zone example's planner
settings (``reverse_confirms``, ``phase1_second_pass: between``); only the sensor model
differs. The calibration is one recording over a 4 cm circle. Prints
a markdown table (found, movements, object interactions, centroid error) per world, shape
and sensor model, and writes found_rate.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from hapticframe_bench._placements import draw_placements

ROOT = Path(__file__).resolve().parents[3]
SEARCH = ROOT / "examples" / "search-ellipse-learned-zone.yaml"
BASELINE = ROOT / "examples" / "search-ellipse-physics-drag.yaml"
CALIBRATE = ROOT / "examples" / "calibrate-learned-zone.yaml"
CIRCLE = "[{shape: circle, center_m: [0.25, 0.32], radius_m: 0.04}]"


def _cli(*args: str) -> int:
    return subprocess.run([sys.executable, "-m", "hapticframe", *args], check=False,
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL).returncode


def main() -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--movements", type=int, nargs="+", default=[12])
    parser.add_argument("--worlds", nargs="+", default=["sandbox", "mpm-sand"])
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    placements = draw_placements(np.random.default_rng(0), args.trials)
    rows = []
    for world in args.worlds:
        common = ["--set", f"robots[0].type={world}", "--set", "run.figures=false",
                  "--set", "run.record=false", "--quiet"]
        # The learned-zone example's planner settings, so that only the sensor model differs.
        planner = ["--set", "planner.reverse_confirms=true",
                   "--set", "planner.phase1_second_pass=between"]
        models: dict[str, tuple[Path, list[str]]] = {"failure-zone-kernel": (BASELINE, planner)}
        for n in args.movements:
            rec = args.out / world / f"calibration-{n}"
            _cli("run", str(SEARCH), "--out", str(rec), "--overwrite", *common,
                 "--set", "zone.model_dir=null", "--set", "run.halt_on_interaction=false",
                 "--set", f"run.max_movements={n}", "--set", f"scene.objects={CIRCLE}")
            fitted = args.out / world / f"learned-{n}"
            code = _cli("train", str(CALIBRATE), "--out", str(fitted), "--overwrite",
                        "--set", f"robots[0].type={world}", "--calibration", str(rec))
            if code == 0:
                models[f"learned-zone, N={n}"] = (SEARCH, ["--set",
                                                           f"zone.model_dir={fitted}/zone"])
        for name, (file, extra) in models.items():
            for shape, shape_placements in placements.items():
                for p in shape_placements:
                    out = args.out / world / name.replace(" ", "").replace(",", "-") / \
                        f"{shape}-{p.index}"
                    objects = json.dumps(p.scene_objects())
                    _cli("run", str(file), "--out", str(out), "--overwrite", *common, *extra,
                         "--set", f"scene.objects={objects}")
                    try:
                        m = json.loads((out / "metrics.json").read_text())
                    except OSError:
                        m = {}
                    rows.append({"world": world, "model": name, "shape": shape,
                                 "index": p.index, "found": bool(m.get("object_found")),
                                 "movements": m.get("movements"),
                                 "interactions": m.get("object_interactions"),
                                 "centroid_error_m": m.get("centroid_error_m")})
                    print(rows[-1], flush=True)
    (args.out / "found_rate.json").write_text(json.dumps(rows, indent=1))
    print("| world | sensor model | shape | found | movements | object interactions | "
          "centroid error (found) |\n|---|---|---|---|---|---|---|")
    keys = sorted({(r["world"], r["model"], r["shape"]) for r in rows},
                  key=lambda k: (args.worlds.index(k[0]), k[1], k[2]))
    for world, model, shape in keys:
        group = [r for r in rows if (r["world"], r["model"], r["shape"]) == (world, model, shape)]
        found = [r for r in group if r["found"]]
        moves = [r["movements"] for r in group if r["movements"] is not None]
        inter = [r["interactions"] for r in group if r["interactions"] is not None]
        err = [r["centroid_error_m"] for r in found if r["centroid_error_m"] is not None]
        print(f"| {world} | {model} | {shape} | {len(found)}/{len(group)} | "
              f"{np.mean(moves):.1f} ± {np.std(moves):.1f} | {np.mean(inter):.1f} | "
              + (f"{100 * np.sqrt(np.mean(np.square(err))):.1f} cm |" if err else "– |"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
