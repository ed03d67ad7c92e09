"""``hapticframe bench search-devices``: the haptic search through emulated devices.

Issue 14, section 6: the chapter 3 search with the wrist force read through a Robotiq FT 300
and the tool's acceleration through a BNO055, both emulated behind pseudo-terminals and
driven by the sandbox's physical truth, the force observer (thesis Eq. 3.10) feeding the
jamming classifier. The same placements and seeds are searched by the two-phase planner
on each chain:

* ``simulation``: the pure simulation (``sandbox-force``), with the same sandbox settings
  (end-effector mass, acceleration profile) as the device chain;
* ``devices``: FT 300 + BNO055 (``port: emulated``) + ``force-observer``;
* ``faults`` (optional, on by default except with ``--quick``; environment variable
  ``HAPTICFRAME_BENCH_FAULTS=0|1`` overrides): the device chain with ``faults: standard``
  on both sensors.

Before the trials, a calibration step drives the sandbox in air (no drag, no jamming, no
contact) through movements in several headings with the emulated sensors, fits the force
observer on the recorded streams (the IMU held onto the FT 300's timestamps) and compares
the recovered ``m_e``, ``R`` and ``ε`` with the emulators' true values.

Outputs in ``options.out_dir``: ``<chain>/`` (each chain's :func:`._search.run_suite`
report and trials), ``search-devices.json`` and ``search-devices.md``.
"""

from __future__ import annotations

import functools
import json
import math
import os
import platform
import resource
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from contextlib import ExitStack
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

import hapticframe
from hapticframe import BenchOptions, Kind, UsageError, atomic_write, validate_mapping
from hapticframe.kinds import (
    BuildContext,
    Component,
    Device,
    ExploratoryMovement,
    FeatureExtractor,
    Robot,
    SampleBatch,
    Sensor,
)

from ._placements import SHAPES
from ._search import SEARCH_PLANNER, run_suite
from ._targets import Target, check_lines, check_targets, load_average
from ._template import search_experiment

__all__ = [
    "CHAINS",
    "DEFAULT_TRIALS",
    "EMULATED_RIG",
    "QUICK_TRIALS",
    "RELATIVE_TOLERANCE",
    "calibrate_observer",
    "chain_experiment",
    "device_targets",
    "run_search_devices",
]

#: Trials per shape by default and with ``--quick``.
DEFAULT_TRIALS = 10
QUICK_TRIALS = 3
#: Issue 14: the device chain's centroid RMSE and Hausdorff within 25 % of the simulation's.
RELATIVE_TOLERANCE = 0.25
#: The chains in report order.
CHAINS = ("simulation", "devices", "faults")

#: The sandbox of every chain: the plate's mass beyond the wrist sensor and a trapezoidal
#: speed profile, so that the FT 300 reads gravity and inertia for the observer to remove.
SANDBOX = {"end_effector_mass_kg": 0.8, "acceleration_m_per_s2": 0.5}

#: The emulated rig's true parameters (what the observer must remove): the FT 300's offset
#: ε and the IMU's mount R_ti (a yaw of 90° about the tool's z axis; see the example).
EMULATED_RIG: dict[str, Any] = {
    "mass_kg": SANDBOX["end_effector_mass_kg"],
    "offset_n": (1.5, -0.8, 2.0),
    "mount_rpy_deg": (0.0, 0.0, 90.0),
    "imu_rotation_wxyz": (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)),
}

#: Plugin types of the device chain and the modules that register them (used when they are
#: not installed as entry points, e.g. in a source checkout not yet reinstalled).
_DEVICE_PLUGINS = {
    (Kind.SENSOR, "robotiq-ft300"): "hapticframe_robotiq.plugin",
    (Kind.SENSOR, "bno055"): "hapticframe_bno055.plugin",
    (Kind.FEATURE_EXTRACTOR, "force-observer"): "hapticframe_force_observer.plugin",
}


def _missing_plugin_modules() -> list[str]:
    """Modules of the device chain's plugins that the installed registry lacks."""
    registry = hapticframe.get_registry()
    return [module for (kind, name), module in _DEVICE_PLUGINS.items()
            if name not in registry.plugins[kind]]


def _device_sensors(faults: str) -> list[dict[str, Any]]:
    return [
        {"id": "wrist", "type": "robotiq-ft300", "inputs": ["arm"], "config": {
            "port": "emulated", "faults": faults,
            # The observer's bias replaces the tare (a tare would remove m_e g twice).
            "tare_s": 0.0, "offset_n": list(EMULATED_RIG["offset_n"])}},
        {"id": "imu", "type": "bno055", "inputs": ["arm"], "config": {
            "port": "emulated", "faults": faults, "mode": "accgyro",
            "mount_rpy_deg": list(EMULATED_RIG["mount_rpy_deg"])}},
    ]


def _observer_config(**overrides: Any) -> dict[str, Any]:
    # Well above the classifier's 3 Hz filter (see examples/search-ellipse-ft300.yaml).
    config: dict[str, Any] = {"cutoff_hz": 20.0, "max_age_s": 0.025}
    config.update(overrides)
    return config


def chain_experiment(
    scene_objects: Sequence[Mapping[str, Any]],
    planner_type: str,
    seed: int,
    name: str,
    *,
    chain: str = "devices",
) -> dict[str, Any]:
    """One trial's experiment on ``chain`` (``"simulation"``, ``"devices"`` or ``"faults"``).

    The template of ``hapticframe bench search`` with the sandbox of :data:`SANDBOX`; for the
    device chains, the sensor ``wrist`` is an emulated FT 300, ``imu`` an emulated BNO055 and
    the classifier reads the feature extractor ``observer`` (force-observer with the
    emulated rig's parameters, :data:`EMULATED_RIG`).
    """
    if chain not in CHAINS:
        raise ValueError(f"chain must be one of {CHAINS}, got {chain!r}")
    data = search_experiment(scene_objects, planner_type, seed, name)
    data["robots"][0]["config"] = dict(SANDBOX)
    if chain == "simulation":
        return data
    data["sensors"] = _device_sensors("standard" if chain == "faults" else "none")
    data["feature_extractors"] = [{
        "id": "observer", "type": "force-observer", "inputs": ["wrist", "imu"],
        "config": _observer_config(
            mass_kg=EMULATED_RIG["mass_kg"],
            imu_rotation_wxyz=list(EMULATED_RIG["imu_rotation_wxyz"]),
            bias_n=list(EMULATED_RIG["offset_n"]),
        ),
    }]
    data["classifiers"][0]["inputs"] = ["observer"]
    return data


# --- calibration ---------------------------------------------------------------------------


def _calibration_experiment(seed: int) -> dict[str, Any]:
    """The sandbox in air (no drag, jamming or contact, no object) with the sensor chain."""
    return {
        "schema_version": 1,
        "name": "search-devices-calibration",
        "seed": seed,
        "scene": {"region": {"x_min_m": 0.0, "x_max_m": 0.75, "y_min_m": 0.0,
                             "y_max_m": 0.50}, "objects": []},
        "robots": [{"id": "arm", "type": "sandbox", "config": {
            **SANDBOX, "drag_coefficient_n_per_m2": 0.0, "jamming_gain_n_per_m": 0.0,
            "contact_stiffness_n_per_m": 0.0}}],
        "sensors": _device_sensors("none"),
        "feature_extractors": [{"id": "observer", "type": "force-observer",
                                "inputs": ["wrist", "imu"], "config": _observer_config()}],
        # The calibration drives the robot itself (_calibration_moves); a closed loop's file
        # still names a planner, which is built and never asked.
        "planners": [{"id": "planner", "type": "coverage"}],
    }


def _calibration_moves(count: int) -> list[ExploratoryMovement]:
    """``count`` 20 cm movements through the region's centre, headings spread over a turn, at
    0.2 m/s: 0.4 s of acceleration at each end, so that the inertia is well excited."""
    centre = np.array([0.375, 0.25])
    moves = []
    for k in range(count):
        heading = 2 * math.pi * k / count
        half = 0.1 * np.array([math.cos(heading), math.sin(heading)])
        moves.append(ExploratoryMovement(centre - half, centre + half, speed_m_per_s=0.2,
                                         label=f"calibration {k}"))
    return moves


def _hold_onto(times: np.ndarray, source_t: np.ndarray, values: np.ndarray,
               ok: np.ndarray, max_age_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample-and-hold of ``values`` (valid rows only) onto ``times``, with a maximum age."""
    keep = ok & np.all(np.isfinite(values), axis=1)
    st, sv = source_t[keep], values[keep]
    index = np.searchsorted(st, times, side="right") - 1
    held = np.full((len(times), values.shape[1]), np.nan)
    fresh = index >= 0
    fresh[fresh] = (times[fresh] - st[index[fresh]]) <= max_age_s
    held[fresh] = sv[index[fresh]]
    return held, fresh


def _concat(batches: Sequence[SampleBatch], channel: str) -> tuple[np.ndarray, ...]:
    batches = [b for b in batches if len(b)]
    t = np.concatenate([b.timestamps_s for b in batches])
    v = np.concatenate([b.channels[channel] for b in batches])
    ok = np.concatenate([np.asarray(b.valid.get(channel, np.ones(len(b), bool)), bool)
                         for b in batches])
    return t, v, ok


def calibrate_observer(
    *, seed: int = 0, movements: int = 6, echo: Callable[[str], None] = lambda _l: None
) -> dict[str, Any]:
    """Fit the force observer from free motions of the sandbox in air, through the devices.

    The sandbox (no drag, jamming or contact) makes ``movements`` 20 cm movements at
    headings spread over a full turn with the speed profile of :data:`SANDBOX`; the emulated
    FT 300 and BNO055 are read after every control step. The IMU's raw acceleration is held
    onto the FT 300's timestamps (as the dataflow's ``hold`` alignment does) and the
    observer's ``fit`` estimates ``m_e``, ``R`` and ``ε``.

    In the sandbox the plate only yaws and accelerates along its heading: in the tool frame
    every movement excites the same direction, so ``fit`` warns that ``R`` is determined
    only up to a twist about it. A mount that is a pure yaw (the emulated rig's) has no such
    twist and is recovered.

    Returns
    -------
    dict
        ``true`` and ``fitted`` parameters (``mass_kg``, ``rotation_wxyz``, ``bias_n``), the
        errors (``mass_error_kg``, ``rotation_error_deg``, ``bias_error_n``), the residual
        force RMS ``raw_rms_n`` (as read: gravity, inertia and offset included) and
        ``residual_rms_n`` (after the fitted observer), the observer's ``training_report``,
        ``samples``, ``warnings`` and ``wall_time_s``.
    """
    from hapticframe.geometry import rotation_matrix_from_wxyz

    started = time.perf_counter()
    experiment = validate_mapping(_calibration_experiment(seed), source="<calibration>",
                                  plugin_modules=_missing_plugin_modules())
    built: dict[str, Component] = {}
    forces: list[SampleBatch] = []
    accels: list[SampleBatch] = []
    caught: list[str] = []
    with ExitStack() as stack:
        for number, entry in enumerate(experiment.components):
            factory = entry.registered.spec.load_factory()
            context = BuildContext(
                id=entry.id,
                rng=np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(number,))),
                inputs={name: built[name] for name in entry.inputs},
                scene=experiment.model.scene,
                progress=False,
            )
            component = factory(entry.config, context)
            stack.callback(component.close)
            built[entry.id] = component
        for component in built.values():
            if isinstance(component, Device):
                component.configure()
                component.activate()
                stack.callback(component.cleanup)
                stack.callback(component.deactivate)
        robot, wrist, imu = built["arm"], built["wrist"], built["imu"]
        observer = built["observer"]
        assert isinstance(robot, Robot) and isinstance(observer, FeatureExtractor)
        assert isinstance(wrist, Sensor) and isinstance(imu, Sensor)
        recordings: list[tuple[list[SampleBatch], list[SampleBatch]]] = []
        for move in _calibration_moves(movements):
            robot.begin(move)
            f_batches, a_batches = [], []
            while robot.step() is not None:
                f_batches.append(wrist.read())
                a_batches.append(imu.read())
            recordings.append((f_batches, a_batches))
            forces += f_batches
            accels += a_batches
        max_age = float(observer.config.max_age_s)
        batches = []
        for f_batches, a_batches in recordings:
            tf, f, f_ok = _concat(f_batches, "force_n")
            ta, a, a_ok = _concat(a_batches, "acceleration_m_per_s2")
            held, fresh = _hold_onto(tf, ta, a, a_ok, max_age)
            batches.append(SampleBatch(
                tf, {"force_n": f, "acceleration_m_per_s2": held},
                {"force_n": f_ok, "acceleration_m_per_s2": fresh}))
        with warnings.catch_warnings(record=True) as issued:
            warnings.simplefilter("always")
            observer.fit(batches)
        caught = [str(w.message) for w in issued]
        report = dict(observer.training_report())  # type: ignore[attr-defined]
        health = {name: built[name].health.as_dict()  # type: ignore[attr-defined]
                  for name in ("wrist", "imu")}
    fitted_r = rotation_matrix_from_wxyz(report["rotation_wxyz"])
    true_r = rotation_matrix_from_wxyz(EMULATED_RIG["imu_rotation_wxyz"])
    cos = (np.trace(fitted_r.T @ true_r) - 1.0) / 2.0
    # What one excited direction u determines: the gain m R u. (m, R) and (-m, R') with
    # R' u = -R u fit equally; the rest of R, and with it ε (which absorbs m R g), is not.
    axes = report.get("excitation_axes")
    u = np.asarray(axes[0], dtype=float) if axes else np.array([1.0, 0.0, 0.0])
    gain_fit = report["mass_kg"] * fitted_r @ u
    gain_true = EMULATED_RIG["mass_kg"] * true_r @ u
    out = {
        "movements": movements,
        "samples": report.get("samples"),
        "true": {"mass_kg": EMULATED_RIG["mass_kg"],
                 "rotation_wxyz": list(EMULATED_RIG["imu_rotation_wxyz"]),
                 "bias_n": list(EMULATED_RIG["offset_n"])},
        "fitted": {"mass_kg": report["mass_kg"], "rotation_wxyz": report["rotation_wxyz"],
                   "bias_n": report["bias_n"]},
        "mass_error_kg": report["mass_kg"] - EMULATED_RIG["mass_kg"],
        "rotation_error_deg": float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))),
        "bias_error_n": float(np.linalg.norm(np.subtract(report["bias_n"],
                                                          EMULATED_RIG["offset_n"]))),
        "excited_axis_imu": u.tolist(),
        "gain_error_relative": float(np.linalg.norm(gain_fit - gain_true)
                                     / np.linalg.norm(gain_true)),
        "raw_rms_n": report.get("residual_rms_before_n"),
        "residual_rms_n": report.get("residual_rms_n"),
        "excited_directions": report.get("excited_directions"),
        "warnings": caught,
        "health": health,
        "training_report": report,
        "wall_time_s": time.perf_counter() - started,
    }
    echo(f"calibration: m_e {out['fitted']['mass_kg']:.4f} kg (true {EMULATED_RIG['mass_kg']}),"
         f" gain m_e R u off by {100 * out['gain_error_relative']:.1f} %,"
         f" R off by {out['rotation_error_deg']:.2f} deg, ε off by {out['bias_error_n']:.3f} N;"
         f" force RMS {out['raw_rms_n']:.3f} N raw -> {out['residual_rms_n']:.3f} N observed")
    return out


# --- trials, costs and health -----------------------------------------------------------


def _cpu_s() -> float:
    """CPU seconds of this process and of its finished children (the trial workers)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def _run_steps(out_dir: Path, run_dir: str) -> int | None:
    """Robot steps of one run, from its trace (None when it wrote none)."""
    trace = out_dir / run_dir / "trace.npz"
    if not trace.exists():
        return None
    with np.load(trace) as data:
        key = next((k for k in data.files if k.startswith("robot/")
                    and k.endswith("/timestamps_s")), None)
        return None if key is None else len(data[key])


def _run_health(out_dir: Path, run_dir: str) -> dict[str, dict[str, int]]:
    path = out_dir / run_dir / "metrics.json"
    if not path.exists():
        return {}
    devices = json.loads(path.read_text(encoding="utf-8")).get("devices") or {}
    return {str(k): {str(c): int(n) for c, n in v.items()} for k, v in devices.items()}


def _chain_record(summary: Mapping[str, Any], out_dir: Path, cpu_s: float,
                  shapes: Sequence[str]) -> dict[str, Any]:
    """Accuracy, per-step cost and summed health of one chain's run_suite summary."""
    runs = summary.get("runs", [])
    steps = [_run_steps(out_dir, r["run_dir"]) for r in runs]
    counted = [s for s in steps if s is not None]
    total_steps = sum(counted) if len(counted) == len(steps) and counted else None
    trial_wall = float(sum(r["wall_time_s"] for r in runs))
    health: dict[str, dict[str, int]] = {}
    for r in runs:
        for device, counters in _run_health(out_dir, r["run_dir"]).items():
            into = health.setdefault(device, {})
            for name, value in counters.items():
                into[name] = into.get(name, 0) + value
    per_shape = {}
    for shape in shapes:
        group = summary.get(shape, {})
        hausdorff = group.get("hausdorff_m") or {}
        per_shape[shape] = {
            "completed": group.get("completed"),
            "found": group.get("found"),
            "centroid_rmse_m": group.get("centroid_rmse_m"),
            "hausdorff_mean_m": hausdorff.get("mean") if isinstance(hausdorff, Mapping)
            else None,
        }
    return {
        **per_shape,
        "runs": len(runs),
        "failed": sum(1 for r in runs if r["status"] != "ok"),
        "steps": total_steps,
        "trial_wall_time_s": trial_wall,
        "cpu_time_s": cpu_s,
        "wall_per_step_ms": None if not total_steps else 1000 * trial_wall / total_steps,
        "cpu_per_step_ms": None if not total_steps else 1000 * cpu_s / total_steps,
        "suite_wall_time_s": summary.get("wall_time_s"),
        "health": health,
    }


def device_targets(chains: Mapping[str, Mapping[str, Any]],
                   shapes: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Issue 14's target per shape: the device chain's centroid RMSE and mean Hausdorff
    distance at most ``1 + RELATIVE_TOLERANCE`` times the pure simulation's (in cm).

    A shape whose figure is missing on either chain (the object never found) gets no
    verdict (``met`` None), never a pass.
    """
    sim, dev = chains.get("simulation", {}), chains.get("devices", {})
    targets, values = [], {}
    factor = 1.0 + RELATIVE_TOLERANCE
    for shape in shapes:
        for key, label in (("centroid_rmse_m", "centroid RMSE"),
                           ("hausdorff_mean_m", "Hausdorff distance")):
            reference = (sim.get(shape) or {}).get(key)
            measured = (dev.get(shape) or {}).get(key)
            name = f"{shape}_{key.removesuffix('_m')}_cm"
            if reference is None:
                continue
            targets.append(Target(name, f"{shape}: device chain {label} (≤ {factor:g} × "
                                  f"simulation's {100 * reference:.2f} cm)",
                                  100 * factor * reference, "cm", digits=2))
            values[name] = None if measured is None else 100 * measured
    return {c.target.name: c.as_dict() for c in check_targets(targets, values)}


def _faults_wanted(options: BenchOptions) -> bool:
    flag = os.environ.get("HAPTICFRAME_BENCH_FAULTS")
    if flag is not None and flag.strip() != "":
        return flag.strip().lower() not in {"0", "false", "no", "off"}
    return not options.quick


def _json_ready(value: Any) -> Any:
    if isinstance(value, Mapping):
        return {str(k): _json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_ready(v) for v in value]
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _cm(value: Any) -> str:
    return "–" if value is None else f"{100 * value:.2f}"


def _ms(value: Any) -> str:
    return "–" if value is None else f"{value:.2f}"


def render_markdown(summary: Mapping[str, Any]) -> str:
    """``search-devices.md``: calibration, accuracy per chain, costs, health, verdicts."""
    cal = summary["calibration"]
    lines = [
        "# Haptic search through emulated devices (issue 14)", "",
        f"Command: `{summary['command']}`  ",
        f"Trials per shape: {summary['trials']}, seed {summary['seed']}, planner "
        f"`{SEARCH_PLANNER}`; load average at start {summary['load_average']}.", "",
        "## Calibration (free motion in air)", "",
        "| | m_e (kg) | R (w, x, y, z) | ε (N) |", "|---|---|---|---|",
    ]
    for row in ("true", "fitted"):
        p = cal[row]
        lines.append(f"| {row} | {p['mass_kg']:.4f} | "
                     f"{', '.join(f'{v:.4f}' for v in p['rotation_wxyz'])} | "
                     f"{', '.join(f'{v:.3f}' for v in p['bias_n'])} |")
    lines += [
        "", f"Identifiable gain m_e R u along the excited IMU axis u = "
        f"{', '.join(f'{v:+.2f}' for v in cal['excited_axis_imu'])}: relative error "
        f"{cal['gain_error_relative']:.3f}.",
        f"Errors: m_e {cal['mass_error_kg']:+.4f} kg, R {cal['rotation_error_deg']:.3f}°, "
        f"ε {cal['bias_error_n']:.3f} N. Force RMS {cal['raw_rms_n']:.3f} N as read "
        f"(gravity, inertia, offset) → {cal['residual_rms_n']:.3f} N after the observer "
        f"({cal['samples']} samples, {cal['movements']} movements).",
    ]
    if cal["warnings"]:
        lines += ["", "Fit warnings: " + "; ".join(cal["warnings"])]
    lines += ["", "## Accuracy and cost per chain", "", *chain_table(summary),
              "", "## Targets", "", *targets_markdown_from(summary["targets"]),
              *health_sections(summary)]
    return "\n".join(lines) + "\n"


def chain_table(summary: Mapping[str, Any]) -> list[str]:
    """Markdown table rows: per chain, found / RMSE / Hausdorff per shape and step costs."""
    shapes = summary["shapes"]
    lines = ["| chain | " + " | ".join(f"{s} found | {s} RMSE (cm) | {s} Hausdorff (cm)"
                                       for s in shapes)
             + " | steps | wall / step (ms) | CPU / step (ms) |",
             "|---" * (1 + 3 * len(shapes) + 3) + "|"]
    for chain, record in summary["chains"].items():
        cells = []
        for shape in shapes:
            s = record[shape]
            cells += [f"{s['found']}/{s['completed']}", _cm(s["centroid_rmse_m"]),
                      _cm(s["hausdorff_mean_m"])]
        lines.append(f"| {chain} | " + " | ".join(cells) + f" | {record['steps']} | "
                     f"{_ms(record['wall_per_step_ms'])} | {_ms(record['cpu_per_step_ms'])} |")
    return lines


def health_sections(summary: Mapping[str, Any]) -> list[str]:
    """Markdown sections of each chain's summed device health (non-zero counters)."""
    lines: list[str] = []
    for chain, record in summary["chains"].items():
        if record["health"]:
            lines += ["", f"## Device health, {chain} (summed over {record['runs']} runs)", ""]
            for device, counters in record["health"].items():
                shown = ", ".join(f"{k} {v}" for k, v in counters.items() if v)
                lines.append(f"- {device}: {shown or 'all zero'}")
    return lines


def targets_markdown_from(targets: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """Markdown rows of the suite's target records (as stored in the JSON)."""
    return [f"- {line}" for line in check_lines(targets)] or ["- no target could be checked"]


def run_search_devices(options: BenchOptions, *, shapes: Sequence[str] = SHAPES,
                       faults: bool | None = None) -> dict[str, Any]:
    """``hapticframe bench search-devices`` (see the module docstring).

    Parameters
    ----------
    options : hapticframe.BenchOptions
        ``trials`` per shape (default 10, 3 with ``quick``), ``seed``, ``workers``,
        ``out_dir``, ``echo``.
    shapes : sequence of str
        Shapes to bury (default: circle and ellipse).
    faults : bool or None
        Run the faulted pass; None: unless ``quick`` (``HAPTICFRAME_BENCH_FAULTS`` decides
        when set).

    Returns
    -------
    dict
        What ``search-devices.json`` holds: ``calibration`` (:func:`calibrate_observer`),
        ``chains`` (per chain: per shape ``found``, ``completed``, ``centroid_rmse_m``,
        ``hausdorff_mean_m``; ``steps``, wall and CPU time per step, summed device
        ``health``), ``targets`` (:func:`device_targets`) and the run's context.
    """
    missing = _missing_plugin_modules()
    if missing:
        raise UsageError(
            "the device chain's plugins are not installed as entry points ("
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
    calibration = calibrate_observer(seed=options.seed, echo=options.echo)
    wanted = ["simulation", "devices"] + (["faults"] if (
        _faults_wanted(options) if faults is None else faults) else [])
    chains: dict[str, dict[str, Any]] = {}
    for chain in wanted:
        chain_dir = out_dir / chain
        options.echo(f"--- chain {chain} ---")
        cpu_before = _cpu_s()
        summary = run_suite(
            replace(options, out_dir=chain_dir, trials=trials),
            experiment_factory=functools.partial(chain_experiment, chain=chain),
            shapes=shapes, planners={"search": SEARCH_PLANNER},
        )
        chains[chain] = _chain_record(summary, chain_dir, _cpu_s() - cpu_before, shapes)
    result: dict[str, Any] = {
        "trials": trials,
        "seed": options.seed,
        "quick": options.quick,
        "shapes": list(shapes),
        "planner": SEARCH_PLANNER,
        "sandbox": SANDBOX,
        "emulated_rig": EMULATED_RIG,
        "calibration": calibration,
        "chains": chains,
        "targets": device_targets(chains, shapes),
        "wall_time_s": time.perf_counter() - started,
        "load_average": load,
        "workers": options.workers,
        "machine": {"platform": platform.platform(),
                    "processor": platform.processor() or platform.machine(),
                    "cpu_count": os.cpu_count(), "python": platform.python_version()},
        "command": " ".join(["hapticframe", "bench", "search-devices", "--trials", str(trials),
                             "--seed", str(options.seed), "--out", str(options.out_dir)]
                            + (["--workers", str(options.workers)] if options.workers else [])
                            + (["--quick"] if options.quick else [])),
    }
    result = _json_ready(result)
    atomic_write(out_dir / "search-devices.json",
                 json.dumps(result, indent=2, allow_nan=False) + "\n")
    atomic_write(out_dir / "search-devices.md", render_markdown(result))
    for line in check_lines(result["targets"]):
        options.echo(line)
    options.echo(f"search-devices done in {result['wall_time_s']:.1f} s: "
                 f"{out_dir / 'search-devices.md'}")
    return result
