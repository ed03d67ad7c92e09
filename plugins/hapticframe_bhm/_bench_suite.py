"""``hapticframe bench bhm``: the map's timing targets, written as bhm.json and bhm.md."""

from __future__ import annotations

import json
import platform
from typing import Any

import numpy as np

from hapticframe import BenchOptions

from ._bench import benchmark_bhm

__all__ = ["run_bhm_bench"]

_ROWS = (
    ("fit_3000", "fit 3,000 labelled points"),
    ("update_200", "add 200 points to that map"),
    ("grid_15000_mean_std", "mean and std on a 15,000-point grid (5 mm)"),
)


def run_bhm_bench(options: BenchOptions) -> dict[str, Any]:
    """Time the Bayesian Hilbert Map against its targets (medians, one BLAS thread)."""
    repeats = 5 if options.quick else (options.trials or 31)
    results = benchmark_bhm(rng_seed=options.seed, repeats=repeats)
    results["repeats"] = repeats
    results["machine"] = {"platform": platform.platform(), "numpy": np.__version__}
    (options.out_dir / "bhm.json").write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    lines = [
        "# Bayesian Hilbert Map timings",
        "",
        f"Median of {repeats} repeats, BLAS threads: {results['blas_threads']}; "
        f"{results['machine']['platform']}, numpy {np.__version__}.",
        "",
        "| operation | target | median | fastest | with region-dependent smoothing |",
        "|---|---|---|---|---|",
    ]
    for key, label in _ROWS:
        lines.append(
            f"| {label} | ≤ {results['targets_ms'][key]:.0f} ms | {results[key + '_ms']:.1f} ms "
            f"| {results[key + '_min_ms']:.1f} ms | {results['rds_' + key + '_ms']:.1f} ms |"
        )
    lines += ["", f"AUC on 20,000 fresh points: {results['auc']:.4f} "
              f"(region-dependent smoothing: {results['rds_auc']:.4f})", ""]
    (options.out_dir / "bhm.md").write_text("\n".join(lines), encoding="utf-8")
    for line in lines[4:]:
        options.echo(line)
    return results
