"""``hapticframe bench search-dynamixel``: the haptic search on a whole emulated rig.

Issue 15, section 5: the chapter 3 search with every device of a real rig emulated — a
Dynamixel gantry (XM430 servos on a pseudo-terminal, driven through the unmodified
``dynamixel_sdk``), the Robotiq FT 300 and the BNO055 of ``search-devices`` — with the sandbox
following the gantry's measured fingertip and computing the physics behind all three
(``sandbox`` with ``follows``). The same placements and seeds are searched on each chain:

* ``simulation``: the pure simulation of ``search-devices`` (the reference);
* ``dynamixel``: gantry + FT 300 + BNO055 + force observer, no faults;
* ``dynamixel-faults`` (on by default except with ``--quick``; ``HAPTICFRAME_BENCH_FAULTS``
  overrides): the same with ``faults: standard`` on the gantry's bus and both sensors.

Outputs in ``options.out_dir``: ``<chain>/`` (each chain's :func:`._search.run_suite` report
and trials), ``search-dynamixel.json`` and ``search-dynamixel.md``.
"""

from __future__ import annotations

import functools
import json
import os
import platform
import time
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import hapticframe
from hapticframe import BenchOptions, Kind, UsageError, atomic_write

from ._placements import SHAPES
from ._search import SEARCH_PLANNER, run_suite
from ._search_devices import (
    DEFAULT_TRIALS,
    QUICK_TRIALS,
    _chain_record,
    _cpu_s,
    _faults_wanted,
    _json_ready,
    chain_experiment,
    chain_table,
    device_targets,
    health_sections,
    targets_markdown_from,
)
from ._targets import check_lines, load_average

__all__ = ["DYNAMIXEL_CHAINS", "GANTRY", "dynamixel_experiment", "run_search_dynamixel"]

#: The chains in report order.
DYNAMIXEL_CHAINS = ("simulation", "dynamixel", "dynamixel-faults")

#: The emulated gantry: the default XM430 axes (x and y 12.5 cm of travel per radian, a
#: 1 cm/rad lead screw for depth) stepped at the sandbox's 100 Hz.
GANTRY: dict[str, Any] = {"port": "emulated", "control_rate_hz": 100.0}


def dynamixel_experiment(
    scene_objects: Sequence[Mapping[str, Any]],
    planner_type: str,
    seed: int,
    name: str,
    *,
    chain: str = "dynamixel",
) -> dict[str, Any]:
    """One trial's experiment on ``chain`` (one of :data:`DYNAMIXEL_CHAINS`).

    ``simulation`` is ``search-devices``'s; the ``dynamixel`` chains take its device chain
    and put robot ``gantry`` (``dynamixel``, emulated, its workspace the scene's region) in
    front: the sandbox ``arm`` follows it (``follows: gantry``), the emulated sensors still
    read the sandbox, and the sensor model locates its measurements with the gantry's poses.
    """
    if chain not in DYNAMIXEL_CHAINS:
        raise ValueError(f"chain must be one of {DYNAMIXEL_CHAINS}, got {chain!r}")
    if chain == "simulation":
        return chain_experiment(scene_objects, planner_type, seed, name, chain="simulation")
    faults = chain == "dynamixel-faults"
    data = chain_experiment(scene_objects, planner_type, seed, name,
                            chain="faults" if faults else "devices")
    region = data["scene"]["region"]
    sandbox = data["robots"][0]
    # The gantry makes the motion: the sandbox's own speed profile does not apply.
    sandbox_config = {k: v for k, v in sandbox["config"].items() if k != "acceleration_m_per_s2"}
    data["robots"] = [
        {"id": "gantry", "type": "dynamixel", "config": {
            **GANTRY, "workspace": dict(region), "faults": "standard" if faults else "none"}},
        {**sandbox, "inputs": ["gantry"], "config": {**sandbox_config, "follows": "gantry"}},
    ]
    for model in data["sensor_models"]:
        model["inputs"] = ["gantry" if i == sandbox["id"] else i for i in model["inputs"]]
    return data


def render_markdown(summary: Mapping[str, Any]) -> str:
    """``search-dynamixel.md``: accuracy and cost per chain, health, verdicts."""
    lines = [
        "# Haptic search on an emulated Dynamixel rig (issue 15)", "",
        f"Command: `{summary['command']}`  ",
        f"Trials per shape: {summary['trials']}, seed {summary['seed']}, planner "
        f"`{SEARCH_PLANNER}`; load average at start {summary['load_average']}.", "",
        *chain_table(summary),
        "", "## Targets (the `dynamixel` chain against `simulation`)", "",
        *targets_markdown_from(summary["targets"]),
        *health_sections(summary),
    ]
    return "\n".join(lines) + "\n"


def run_search_dynamixel(options: BenchOptions, *, shapes: Sequence[str] = SHAPES,
                         faults: bool | None = None) -> dict[str, Any]:
    """``hapticframe bench search-dynamixel`` (see the module docstring).

    Parameters
    ----------
    options : hapticframe.BenchOptions
        ``trials`` per shape (default 10, 3 with ``quick``), ``seed``, ``workers``,
        ``out_dir``, ``echo``.
    shapes : sequence of str
        Shapes to bury (default: circle and ellipse).
    faults : bool or None
        Run the faulted chain; None: unless ``quick`` (``HAPTICFRAME_BENCH_FAULTS`` decides
        when set).

    Returns
    -------
    dict
        What ``search-dynamixel.json`` holds: ``chains`` (per chain: per shape ``found``,
        ``completed``, ``centroid_rmse_m``, ``hausdorff_mean_m``; ``steps``, wall and CPU
        time per step, summed device ``health``), ``targets`` (centroid RMSE and mean
        Hausdorff of ``dynamixel`` within 25 % of ``simulation``'s) and the run's context.
    """
    registry = hapticframe.get_registry()
    missing = [name for kind, name in ((Kind.ROBOT, "dynamixel"), (Kind.SENSOR, "robotiq-ft300"),
                                       (Kind.SENSOR, "bno055"),
                                       (Kind.FEATURE_EXTRACTOR, "force-observer"))
               if name not in registry.plugins[kind]]
    if missing:
        raise UsageError("the rig's plugins are not installed as entry points ("
                         + ", ".join(missing) + "): reinstall hapticframe (pip install -e .)")
    trials = options.trials if options.trials is not None else (
        QUICK_TRIALS if options.quick else DEFAULT_TRIALS)
    if not isinstance(trials, int) or isinstance(trials, bool) or trials < 1:
        raise ValueError(f"trials must be a positive int, got {trials!r}")
    shapes = tuple(shapes)
    out_dir = Path(options.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    load = load_average()
    started = time.perf_counter()
    wanted = ["simulation", "dynamixel"] + (["dynamixel-faults"] if (
        _faults_wanted(options) if faults is None else faults) else [])
    chains: dict[str, dict[str, Any]] = {}
    for chain in wanted:
        chain_dir = out_dir / chain
        options.echo(f"--- chain {chain} ---")
        cpu_before = _cpu_s()
        summary = run_suite(
            replace(options, out_dir=chain_dir, trials=trials),
            experiment_factory=functools.partial(dynamixel_experiment, chain=chain),
            shapes=shapes, planners={"search": SEARCH_PLANNER},
        )
        chains[chain] = _chain_record(summary, chain_dir, _cpu_s() - cpu_before, shapes)
    compared = {"simulation": chains["simulation"], "devices": chains["dynamixel"]}
    result: dict[str, Any] = {
        "trials": trials,
        "seed": options.seed,
        "quick": options.quick,
        "shapes": list(shapes),
        "planner": SEARCH_PLANNER,
        "gantry": GANTRY,
        "chains": chains,
        "targets": device_targets(compared, shapes),
        "wall_time_s": time.perf_counter() - started,
        "load_average": load,
        "workers": options.workers,
        "machine": {"platform": platform.platform(),
                    "processor": platform.processor() or platform.machine(),
                    "cpu_count": os.cpu_count(), "python": platform.python_version()},
        "command": " ".join(["hapticframe", "bench", "search-dynamixel", "--trials",
                             str(trials), "--seed", str(options.seed), "--out",
                             str(options.out_dir)]
                            + (["--workers", str(options.workers)] if options.workers else [])
                            + (["--quick"] if options.quick else [])),
    }
    result = _json_ready(result)
    atomic_write(out_dir / "search-dynamixel.json",
                 json.dumps(result, indent=2, allow_nan=False) + "\n")
    atomic_write(out_dir / "search-dynamixel.md", render_markdown(result))
    for line in check_lines(result["targets"]):
        options.echo(line)
    options.echo(f"search-dynamixel done in {result['wall_time_s']:.1f} s: "
                 f"{out_dir / 'search-dynamixel.md'}")
    return result
