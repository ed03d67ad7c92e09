"""``hapticframe bench bhm``: the Bayesian Hilbert map's timing targets (bhm.json, bhm.md).

The map is timed on the synthetic two-object scene of the mapping notes (§7).
Scene: 0.75 x 0.50 m, a disc of radius 6 cm at (0.25, 0.25) m and a 10 x 4 cm rectangle
centred at (0.55, 0.30) m; labelled points uniform in the region, 3 % of labels flipped.
Timings are medians over repeats with BLAS limited to one thread (threadpoolctl) when
available; absolute numbers depend on the CPU and BLAS build.
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import json
import platform
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import rankdata

from hapticframe import BenchOptions, Circle, Polygon, Scene, atomic_write
from hapticframe.kinds import BuildContext, Observations
from hapticframe_bhm import BayesianHilbertMap, BayesianHilbertMapConfig
from hapticframe_gp_occupancy import GPOccupancyConfig, GPOccupancyMap

from ._targets import Target, check_targets, load_average, load_note

__all__ = [
    "BHM_TARGETS",
    "GP_SIZES",
    "benchmark_bhm",
    "benchmark_gp_scaling",
    "crossover",
    "labelled_points",
    "log_loss",
    "roc_auc",
    "run_bhm_bench",
    "two_object_scene",
]

#: The map's targets on one core (median wall time, ms).
BHM_TARGETS = (
    Target("fit_3000_ms", "fit 3,000 labelled points", 25.0, "ms"),
    Target("update_200_ms", "add 200 points to that map", 2.0, "ms"),
    Target("grid_15000_mean_std_ms", "mean and std on a 15,000-point grid (5 mm)", 40.0, "ms"),
)


def two_object_scene() -> Scene:
    """The §7 scene: a 6 cm disc and a 10 x 4 cm rectangle in a 75 x 50 cm region."""
    rectangle = [(-0.05, -0.02), (0.05, -0.02), (0.05, 0.02), (-0.05, 0.02)]
    return Scene(
        objects=[
            Circle(center_m=(0.25, 0.25), radius_m=0.06),
            Polygon(center_m=(0.55, 0.30), vertices_m=rectangle),
        ]
    )


def labelled_points(
    scene: Scene, count: int, rng: np.random.Generator, flip_fraction: float = 0.03
) -> Observations:
    """``count`` uniform points with 0/1 occupancy labels, a fraction of them flipped."""
    r = scene.region
    low = np.array([r.x_min_m, r.y_min_m])
    size = np.array([r.x_max_m - r.x_min_m, r.y_max_m - r.y_min_m])
    points = low + rng.random((count, 2)) * size
    labels = scene.occupied(points).astype(np.float64)
    flip = rng.random(count) < flip_fraction
    labels[flip] = 1.0 - labels[flip]
    return Observations(points, labels)


def roc_auc(labels: NDArray[np.bool_], scores: NDArray[np.float64]) -> float:
    """Area under the ROC curve via the Mann–Whitney rank statistic (ties averaged)."""
    labels = np.asarray(labels, dtype=bool)
    positives, negatives = int(labels.sum()), int((~labels).sum())
    if positives == 0 or negatives == 0:
        raise ValueError("AUC needs both classes")
    ranks = rankdata(scores)
    return float((ranks[labels].sum() - positives * (positives + 1) / 2) / (positives * negatives))


def log_loss(labels: NDArray[np.bool_], probabilities: NDArray[np.float64]) -> float:
    """Mean negative log likelihood of 0/1 ``labels`` (probabilities clipped to 1e-9)."""
    p = np.clip(np.asarray(probabilities, dtype=np.float64), 1e-9, 1.0 - 1e-9)
    return float(-np.mean(np.where(np.asarray(labels, dtype=bool), np.log(p), np.log1p(-p))))


@contextlib.contextmanager
def _single_blas_thread() -> Iterator[str]:
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        yield "not limited (threadpoolctl is not installed)"
        return
    with threadpool_limits(limits=1):
        yield "1 (threadpoolctl)"


def _timed_ms(
    run: Callable[[], Any], repeats: int, setup: Callable[[], Any] | None = None
) -> tuple[float, float]:
    """Median and minimum wall time of ``run`` in milliseconds (``setup`` is not timed)."""
    times = []
    for _ in range(repeats):
        if setup is not None:
            setup()
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3), float(np.min(times) * 1e3)


def _build(config: BayesianHilbertMapConfig, seed: int, scene: Scene) -> BayesianHilbertMap:
    context = BuildContext(id="bhm-bench", rng=np.random.default_rng(seed), scene=scene)
    return BayesianHilbertMap(config, context)


def _last_iterations(bhm: BayesianHilbertMap) -> int:
    """Iterations of the map's last variational update (``fit`` and ``update`` record one)."""
    info = bhm.last_update_info
    if info is None:
        raise RuntimeError("the map has recorded no update yet")
    return info.iterations


def benchmark_bhm(rng_seed: int = 0, repeats: int = 15) -> dict[str, Any]:
    """Time fit (3,000 points), sequential update (+200 points) and a 15,000-point grid.

    Parameters
    ----------
    rng_seed : int
        Seed of the data and of the maps' Monte-Carlo samples.
    repeats : int
        Timed repetitions per figure (the median is reported).

    Returns
    -------
    dict
        Median times ``fit_3000_ms``, ``update_200_ms``, ``grid_15000_mean_std_ms``
        (:meth:`probability_grid` at 5 mm) and ``query_15000_mean_std_ms`` (generic
        :meth:`query` on the same points), each also as ``*_min_ms`` (fastest repeat), with
        one length scale (as the targets assume) and with region-dependent smoothing
        (``rds_*``); iteration counts, whether the update triggered a refit, the AUC on
        20,000 fresh points, and the BLAS thread setting.
    """
    rng = np.random.default_rng(rng_seed)
    scene = two_object_scene()
    train = labelled_points(scene, 3000, rng)
    extra = labelled_points(scene, 200, rng)
    test = labelled_points(scene, 20_000, rng, flip_fraction=0.0)
    results: dict[str, Any] = {"platform": platform.processor() or platform.machine()}

    with _single_blas_thread() as threads:
        results["blas_threads"] = threads
        for prefix, smoothing in (("", False), ("rds_", True)):
            config = BayesianHilbertMapConfig(region_dependent_smoothing=smoothing)
            bhm = _build(config, rng_seed, scene)
            bhm.fit(train)  # warm-up, and the iteration count of the first batch
            results[f"{prefix}fit_iterations"] = _last_iterations(bhm)
            # functools.partial binds this iteration's map (a lambda would look it up late).
            fit_train = functools.partial(bhm.fit, train)
            timings = {
                "fit_3000": _timed_ms(fit_train, repeats),
                "update_200": _timed_ms(
                    functools.partial(bhm.update, extra), repeats, setup=fit_train
                ),
            }
            bhm.fit(train)
            refits_before = bhm.refits
            bhm.update(extra)
            results[f"{prefix}update_iterations"] = _last_iterations(bhm)
            results[f"{prefix}update_refitted"] = bhm.refits > refits_before
            grid_points = np.stack(
                np.meshgrid(*scene.region.to_region().grid(0.005), indexing="xy"), axis=-1
            ).reshape(-1, 2)
            results[f"{prefix}grid_points"] = int(grid_points.shape[0])
            timings["grid_15000_mean_std"] = _timed_ms(
                functools.partial(bhm.probability_grid, 0.005), repeats
            )
            timings["query_15000_mean_std"] = _timed_ms(
                functools.partial(bhm.query, grid_points), max(3, repeats // 3)
            )
            for name, (median, fastest) in timings.items():
                results[f"{prefix}{name}_ms"] = median
                results[f"{prefix}{name}_min_ms"] = fastest
            estimate = bhm.query(test.points_m)
            results[f"{prefix}auc"] = roc_auc(test.targets > 0.5, estimate.mean)
            results[f"{prefix}log_loss"] = log_loss(test.targets > 0.5, estimate.mean)
        # Automorphing kernels (issue 19 §1): learning refits all data several times, so
        # fewer repeats; the add right after the fit is sequential (no re-learning).
        config = BayesianHilbertMapConfig(automorphing_kernels=True)
        bhm = _build(config, rng_seed, scene)
        fit_train = functools.partial(bhm.fit, train)
        few = max(1, repeats // 5)
        for name, (median, fastest) in {
            "fit_3000": _timed_ms(fit_train, few),
            "update_200": _timed_ms(functools.partial(bhm.update, extra), few, setup=fit_train),
        }.items():
            results[f"am_{name}_ms"], results[f"am_{name}_min_ms"] = median, fastest
        bhm.fit(train)
        bhm.update(extra)
        results["am_grid_15000_mean_std_ms"] = _timed_ms(
            functools.partial(bhm.probability_grid, 0.005), few)[0]
        estimate = bhm.query(test.points_m)
        results["am_auc"] = roc_auc(test.targets > 0.5, estimate.mean)
        results["am_log_loss"] = log_loss(test.targets > 0.5, estimate.mean)
        scales = bhm.length_scales
        results["am_length_scales_cm"] = {
            f"{100 * value:.2f}": int(count)
            for value, count in zip(*np.unique(scales, return_counts=True), strict=True)
        }
    results["targets_ms"] = {t.name.removesuffix("_ms"): t.limit for t in BHM_TARGETS}
    return results


#: Observation counts of the GP-against-BHM rows (issue 19 §2: 1k to 30k); 300 shows which
#: side of 1k a crossover lies.
GP_SIZES = (300, 1000, 3000, 10_000, 30_000)
#: Largest set the exact GP is timed on: its kernel matrix holds N² doubles (10k: 800 MB,
#: 30k: 7.2 GB) and its variance costs N² per queried point.
GP_EXACT_MAX = 10_000
#: Largest set whose exact GP is also queried on the 15,000-point grid (15,000 N² flops).
_GP_EXACT_GRID_MAX = 3000


def _timed_fit(the_map: Any, train: Observations, probe: NDArray[np.float64],
               repeats: int) -> tuple[float, float]:
    """Median and fastest ms of ``fit`` then a one-point query: the map ready to answer
    (the GP factorises, the BHM caches its covariance, at their first query)."""
    def run() -> None:
        the_map.fit(train)
        the_map.query(probe[:1])

    return _timed_ms(run, repeats)


def benchmark_gp_scaling(
    rng_seed: int = 0,
    repeats: int = 3,
    sizes: tuple[int, ...] = GP_SIZES,
    exact_max: int = GP_EXACT_MAX,
    exact_grid_max: int = _GP_EXACT_GRID_MAX,
    grid_spacing_m: float = 0.005,
) -> dict[str, Any]:
    """Time and accuracy of ``gp-occupancy`` (exact and inducing points) beside the BHM.

    For each size ``N`` in ``sizes``: ``N`` labelled points of the §7 scene (3 % flipped).
    Maps: the BHM (defaults), ``gp-inducing`` (default 2.5 cm inducing grid),
    ``gp-inducing-5cm`` (inducing points on the BHM's 5 cm hinge spacing) and ``gp-exact``.
    Per map: ``fit_ms`` (fit, then a one-point query: ready to answer), ``query_1000_ms``
    (mean and std at 1,000 scattered points), ``grid_15000_ms`` (mean and std on the 5 mm
    grid; the exact GP only up to ``exact_grid_max``), AUC and log loss on 5,000 fresh
    unflipped points. The exact GP runs up to ``exact_max``. Medians of ``repeats`` up to
    3,000 points, one run beyond. ``crossover`` holds, per GP variant and timing, where its
    time first exceeds the BHM's (:func:`crossover`).
    """
    rng = np.random.default_rng(rng_seed)
    scene = two_object_scene()
    test = labelled_points(scene, 5000, rng, flip_fraction=0.0)
    scattered = labelled_points(scene, 1000, rng).points_m
    rows: list[dict[str, Any]] = []
    context = BuildContext(id="gp-bench", rng=np.random.default_rng(rng_seed), scene=scene)
    for n in sizes:
        train = labelled_points(scene, n, rng)
        times = repeats if n <= 3000 else 1
        maps: list[tuple[str, Any]] = [("bhm", _build(BayesianHilbertMapConfig(), rng_seed,
                                                      scene))]
        maps.append(("gp-inducing", GPOccupancyMap(GPOccupancyConfig(method="inducing"),
                                                   context)))
        # Inducing points as sparse as the BHM's hinges: the same basis size, M ~ D.
        maps.append(("gp-inducing-5cm", GPOccupancyMap(
            GPOccupancyConfig(method="inducing", inducing_spacing_m=0.05), context)))
        if n <= exact_max:
            maps.append(("gp-exact", GPOccupancyMap(GPOccupancyConfig(method="exact"),
                                                    context)))
        for name, the_map in maps:
            fit_ms, fit_min_ms = _timed_fit(the_map, train, scattered, times)
            row: dict[str, Any] = {"map": name, "observations": n, "fit_ms": fit_ms,
                                   "fit_min_ms": fit_min_ms}
            row["query_1000_ms"] = _timed_ms(functools.partial(the_map.query, scattered),
                                             times)[0]
            row["grid_15000_ms"] = None
            if name != "gp-exact" or n <= exact_grid_max:
                row["grid_15000_ms"] = _timed_ms(
                    functools.partial(the_map.probability_grid, grid_spacing_m), times)[0]
            mean = the_map.query(test.points_m).mean
            row["auc"] = roc_auc(test.targets > 0.5, mean)
            row["log_loss"] = log_loss(test.targets > 0.5, mean)
            rows.append(row)
    bhm = {r["observations"]: r for r in rows if r["map"] == "bhm"}
    found: dict[str, Any] = {}
    for name in ("gp-exact", "gp-inducing", "gp-inducing-5cm"):
        for timing in ("fit_ms", "query_1000_ms", "grid_15000_ms"):
            pairs = [(r["observations"], r[timing] / bhm[r["observations"]][timing])
                     for r in rows if r["map"] == name and r[timing] is not None]
            found[f"{name}:{timing}"] = crossover(pairs)
    return {"sizes": list(sizes), "exact_max": exact_max, "rows": rows, "crossover": found}


def crossover(ratios: list[tuple[int, float]]) -> dict[str, Any]:
    """Where a time ratio (GP over BHM) first rises through 1, by size.

    ``ratios``: ``(N, ratio)`` in increasing ``N``. Returns ``{"observations": N*, "how":
    ...}``: ``N*`` interpolated log-linearly between the sizes either side of the first
    rise through 1 ("between"), the smallest size when the GP is slower at every size
    ("below"), or None when it is faster at every size ("beyond").
    """
    if not ratios:
        return {"observations": None, "how": "not measured"}
    if ratios[0][1] > 1.0:
        return {"observations": ratios[0][0], "how": "below"}
    for (n1, r1), (n2, r2) in itertools.pairwise(ratios):
        if r1 <= 1.0 < r2:
            share = -np.log(r1) / (np.log(r2) - np.log(r1))
            value = float(np.exp(np.log(n1) + share * (np.log(n2) - np.log(n1))))
            return {"observations": round(value), "how": "between"}
    return {"observations": None, "how": "beyond"}


def _gp_lines(gp: dict[str, Any]) -> list[str]:
    """The GP-against-BHM table of ``bhm.md``."""
    def ms(value: float | None) -> str:
        return "—" if value is None else f"{value:,.1f} ms"

    lines = [
        "## GP occupancy against the BHM (issue 19 §2)", "",
        "| observations | map | fit (ready to answer) | query 1,000 points | grid 15,000 "
        "| AUC | log loss |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in gp["rows"]:
        lines.append(
            f"| {row['observations']:,} | {row['map']} | {ms(row['fit_ms'])} "
            f"| {ms(row['query_1000_ms'])} | {ms(row['grid_15000_ms'])} "
            f"| {row['auc']:.4f} | {row['log_loss']:.4f} |"
        )
    lines += ["", "Where the GP's time first exceeds the BHM's:", ""]
    for key, value in gp["crossover"].items():
        name, timing = key.split(":")
        how, count = value["how"], value["observations"]
        if how == "below":
            where = f"already at {count:,} (the smallest size)"
        elif how == "between":
            where = f"at about {count:,} observations"
        else:
            where = "never in the sizes measured" if how == "beyond" else how
        lines.append(f"- {name}, {timing.removesuffix('_ms').replace('_', ' ')}: {where}")
    return [*lines, ""]


def run_bhm_bench(options: BenchOptions) -> dict[str, Any]:
    """Time the Bayesian Hilbert Map against its targets (medians, one BLAS thread).

    Writes ``bhm.json`` (every figure of :func:`benchmark_bhm`, plus ``targets``: per
    target its value, limit and whether it was met) and ``bhm.md``, and prints each target
    beside its measurement with a verdict. ``--quick`` takes 5 repeats, ``--trials N`` N
    (default 31).
    """
    repeats = 5 if options.quick else (options.trials or 31)
    results = benchmark_bhm(rng_seed=options.seed, repeats=repeats)
    # The GP rows: --quick takes 1,000 and 3,000 observations, once each.
    results["gp"] = benchmark_gp_scaling(
        rng_seed=options.seed, repeats=1 if options.quick else min(repeats, 3),
        sizes=(1000, 3000) if options.quick else GP_SIZES,
        exact_max=3000 if options.quick else GP_EXACT_MAX,
        exact_grid_max=1000 if options.quick else _GP_EXACT_GRID_MAX)
    results["repeats"] = repeats
    results["machine"] = {"platform": platform.platform(), "numpy": np.__version__,
                          "load_average_1min": load_average()}
    checks = check_targets(BHM_TARGETS, results)
    results["targets"] = {c.target.name: c.as_dict() for c in checks}
    results["targets_met"] = all(c.met for c in checks)
    atomic_write(options.out_dir / "bhm.json", json.dumps(results, indent=2) + "\n")
    lines = [
        "# Bayesian Hilbert Map timings",
        "",
        f"Median of {repeats} repeats, BLAS threads: {results['blas_threads']}; "
        f"{results['machine']['platform']}, numpy {np.__version__}; "
        f"{load_note(results['machine']['load_average_1min'])}.",
        "",
        "| operation | target | median | fastest | verdict | with region-dependent smoothing |",
        "|---|---|---|---|---|---|",
    ]
    for check in checks:
        key = check.target.name.removesuffix("_ms")
        lines.append(
            f"| {check.target.label} | ≤ {check.target.limit:.0f} ms "
            f"| {results[key + '_ms']:.1f} ms "
            f"| {results[key + '_min_ms']:.1f} ms | {check.verdict} "
            f"| {results['rds_' + key + '_ms']:.1f} ms |"
        )
    lines += ["", f"AUC on 20,000 fresh points: {results['auc']:.4f} "
              f"(region-dependent smoothing: {results['rds_auc']:.4f})", ""]
    if "am_auc" in results:
        lines += _kernel_lines(results)
    lines += _gp_lines(results["gp"])
    atomic_write(options.out_dir / "bhm.md", "\n".join(lines))
    options.echo(f"Median of {repeats} repeats, BLAS threads: {results['blas_threads']}; "
                 f"{load_note(results['machine']['load_average_1min'])}")
    for check in checks:
        options.echo(check.line())
    options.echo(f"AUC on 20,000 fresh points: {results['auc']:.4f}")
    for key, value in results["gp"]["crossover"].items():
        if key.endswith(":fit_ms"):
            options.echo(f"{key.split(':')[0]} fit slower than the BHM's: {value['how']} "
                         f"{value['observations']} observations")
    if "am_auc" in results:
        options.echo(f"automorphing kernels: fit {results['am_fit_3000_ms']:.0f} ms, "
                     f"AUC {results['am_auc']:.4f}, log loss {results['am_log_loss']:.4f} "
                     f"(stationary: {results['fit_3000_ms']:.0f} ms, {results['auc']:.4f}, "
                     f"{results['log_loss']:.4f})")
    return results


def _kernel_lines(results: dict[str, Any]) -> list[str]:
    """The kernels table of ``bhm.md``: stationary, two-bandwidth and automorphing."""
    lines = [
        "## Kernels (issue 19 §1)", "",
        "| kernel | fit 3,000 (median) | add 200 | grid 15,000 | AUC | log loss |",
        "|---|---|---|---|---|---|",
    ]
    for label, prefix in (("stationary", ""), ("two-bandwidth", "rds_"),
                          ("automorphing", "am_")):
        lines.append(
            f"| {label} | {results[prefix + 'fit_3000_ms']:.1f} ms "
            f"| {results[prefix + 'update_200_ms']:.1f} ms "
            f"| {results[prefix + 'grid_15000_mean_std_ms']:.1f} ms "
            f"| {results[prefix + 'auc']:.4f} | {results[prefix + 'log_loss']:.4f} |"
        )
    lines += ["", "Learned length scales (cm: hinges): " + ", ".join(
        f"{k}: {v}" for k, v in results["am_length_scales_cm"].items()), ""]
    return lines
