"""The ``faults`` family of ``hapticframe bench fuzz``: fault schedules per device.

A device of the emulated examples (the FT 300, the BNO055, the Dynamixel gantry) gets a
random ``faults`` setting: a named schedule (right or misspelt), or a list of entries whose
kind is the device's own, another device's or misspelt, whose timing (``at_s``,
``rate_hz``, ``duration_s``) is ordinary or out of range (NaN, infinity, 1e12, 1e308,
negative, a boolean, a string), and whose parameters are the kind's own or not, in range or
not. The experiment is validated here; a refusal must be located (a line) with exit 2. An
accepted one whose settings the device cannot have (a kind it lacks, a time that is not a
finite number in range) is a finding (``accepted_invalid``); the other accepted ones are
run, capped (one movement; at most ``--trials``/5 runs), in a child process, and must end
cleanly.
"""

from __future__ import annotations

import copy
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hapticframe import ExperimentError, HapticframeError, validate_file
from hapticframe_bench._fuzz_common import Case, Outcome, classify, hapticframe_command

__all__ = ["DEVICE_KINDS", "check_fault_case", "generate_fault_cases"]

EXAMPLES = ("search-ellipse-ft300.yaml", "search-ellipse-dynamixel.yaml",
            "free-motion-ft300.yaml")
#: The harness's byte-level kinds, which every serial device takes.
BYTE_KINDS = ("drop_bytes", "garbage", "fragment", "stall", "disconnect")
#: Each emulated device's own kinds and their parameters (as its plugin declares them, for
#: telling a kind the device lacks from one it has).
DEVICE_KINDS: dict[str, dict[str, tuple[str, ...]]] = {
    "robotiq-ft300": {k: () for k in (
        "boots_streaming", "partial_jam", "bad_crc", "stream_stop", "saturation", "frozen",
        "no_reply", "modbus_bad_crc", "wrong_slave", "exception_reply", "missing_echo",
        "dead")} | {"frame_drop_bytes": ("count",), "header_in_payload": ("offset",),
                    "offset_drift": ("rate_n_per_s",)},
    "bno055": {"bus_overrun": ("count",), "status": ("count", "code"), "no_reply": ("count",),
               "rx_stall": ("count",), "partial_reply": ("count", "keep"),
               "wrong_length": ("count", "delta"), "stale_bytes": ("count",), "reset": (),
               "calib_drop": ("stat",), "bad_quaternion": ("scale",),
               "bad_gravity": ("scale",)},
    "dynamixel": {"no_reply": ("id",), "bad_crc": ("id",), "error_code": ("id", "error"),
                  "late_reply": ("id", "delay_s"), "late_duplicate": ("id",),
                  "junk": ("id", "count", "half"), "stuffing": ("id", "position"),
                  "sync_missing": ("id",), "hardware_error": ("id", "bit"),
                  "current_spike": ("id", "amps"), "power_loss": ("id",)},
}
_BYTE_PARAMS = {"drop_bytes": ("count",), "garbage": ("count",), "stall": ("drop",),
                "fragment": (), "disconnect": ()}
MISSPELT = ("bad_crcc", "stal", "Stall", "garbage ", "", "disconect", "drop-bytes", "BAD_CRC",
            "frozen\x00", "z" * 300)
NAMED = ("none", "standard", "Standard", "standrad", "", "all", "none ")
BAD_NUMBERS: tuple[Any, ...] = (math.nan, math.inf, -math.inf, -1.0, 1e12, 1e308, -1e-300,
                                True, "x", None, 1e6 + 1, [], 0)
GOOD_PARAM_VALUES: tuple[Any, ...] = (0, 1, 2, 3, 0.5, 7)
BAD_PARAM_VALUES: tuple[Any, ...] = (1e15, -1e15, math.nan, math.inf, "x", 1.5, -1, 10**20,
                                     True, None, [1])


def _pick(rng: np.random.Generator, values: tuple[Any, ...] | list[Any]) -> Any:
    return values[int(rng.integers(len(values)))]


def _entry(device: str, rng: np.random.Generator) -> dict[str, Any]:
    own = {**{k: _BYTE_PARAMS[k] for k in BYTE_KINDS}, **DEVICE_KINDS[device]}
    others = sorted({k for d, kinds in DEVICE_KINDS.items() if d != device for k in kinds}
                    - set(own))
    draw = rng.random()
    kind: Any = (_pick(rng, sorted(own)) if draw < 0.55 else _pick(rng, others)
                 if draw < 0.75 else _pick(rng, MISSPELT) if draw < 0.95
                 else _pick(rng, (3, None, ["stall"])))
    entry: dict[str, Any] = {"kind": kind}
    timing = rng.random()
    if timing < 0.45:
        entry["at_s"] = float(rng.uniform(0, 3)) if rng.random() < 0.6 else \
            _pick(rng, BAD_NUMBERS)
    elif timing < 0.9:
        entry["rate_hz"] = float(rng.uniform(0.1, 5)) if rng.random() < 0.6 else \
            _pick(rng, BAD_NUMBERS)
    elif timing < 0.95:
        entry.update(at_s=1.0, rate_hz=1.0)
    if rng.random() < 0.4:
        entry["duration_s"] = float(rng.uniform(0, 0.3)) if rng.random() < 0.6 else \
            _pick(rng, BAD_NUMBERS)
    names = list(own.get(kind, ())) if isinstance(kind, str) else []
    if rng.random() < 0.5:
        params: dict[str, Any] = {}
        for name in names[: int(rng.integers(len(names) + 1))]:
            params[name] = _pick(rng, GOOD_PARAM_VALUES) if rng.random() < 0.6 else \
                _pick(rng, BAD_PARAM_VALUES)
        if rng.random() < 0.3:
            params[_pick(rng, ("position", "count", "zz", "delay"))] = \
                _pick(rng, GOOD_PARAM_VALUES + BAD_PARAM_VALUES)
        entry["params"] = params
    return entry


def generate_fault_cases(count: int, seed: int, examples_dir: Path) -> list[Case]:
    """``count`` cases: a device of an emulated example, a random ``faults`` setting."""
    rng = np.random.default_rng(seed)
    bases = {name: yaml.safe_load((examples_dir / name).read_text(encoding="utf-8"))
             for name in EXAMPLES}
    cases = []
    for _ in range(count):
        name = _pick(rng, EXAMPLES)
        data = copy.deepcopy(bases[name])
        slots = [(section, i, item["type"]) for section in ("robots", "sensors")
                 for i, item in enumerate(data.get(section) or [])
                 if item.get("type") in DEVICE_KINDS]
        section, index, device = _pick(rng, slots)
        faults: Any
        if rng.random() < 0.15:
            faults = _pick(rng, NAMED)
        else:
            faults = [_entry(device, rng) for _ in range(int(rng.integers(1, 4)))]
        data[section][index].setdefault("config", {})["faults"] = faults
        shown = yaml.safe_dump(faults, default_flow_style=True, width=10_000).strip()
        cases.append(Case("faults", device, f"{name} {section}[{index}] ({device}).faults = "
                          f"{shown[:150]}", {"example": name, "experiment": data,
                                             "device": device, "faults": faults}))
    return cases


def _finite_in(value: Any, low: float, high: float, *, low_open: bool = False) -> bool:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    if not math.isfinite(value):
        return False
    return (low < value if low_open else low <= value) and value <= high


def cannot_have(device: str, faults: Any) -> str | None:
    """Why a device cannot have ``faults`` (a kind it lacks, a timing out of range), or
    None when it might (its parameters' ranges are the validator's to check)."""
    if isinstance(faults, str):
        return None if faults in ("none", "standard") else f"no schedule named {faults!r}"
    own = {**_BYTE_PARAMS, **DEVICE_KINDS[device]}
    for entry in faults:
        kind = entry.get("kind")
        if not isinstance(kind, str) or kind not in own:
            return f"{device} has no fault kind {kind!r}"
        if ("at_s" in entry) == ("rate_hz" in entry):
            return "not exactly one of at_s and rate_hz"
        if "at_s" in entry and not _finite_in(entry["at_s"], 0, 1e6):
            return f"at_s {entry['at_s']!r}"
        if "rate_hz" in entry and not _finite_in(entry["rate_hz"], 0, 1000, low_open=True):
            return f"rate_hz {entry['rate_hz']!r}"
        if "duration_s" in entry and not _finite_in(entry["duration_s"], 0, 1e6):
            return f"duration_s {entry['duration_s']!r}"
        for name, value in (entry.get("params") or {}).items():
            if name not in own[kind]:
                return f"{kind} reads no parameter {name!r}"
            if not (isinstance(value, str) or _finite_in(value, -math.inf, math.inf)):
                return f"params.{name} {value!r}"
    return None


def check_fault_case(case: Case, workdir: Path, *, run: bool = True) -> Outcome:
    """Validate the case's experiment; an accepted one is checked against what the device
    can have and (``run``) run for one movement in a child process."""
    started = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    experiment = workdir / "experiment.yaml"
    experiment.write_text(yaml.safe_dump(case.data["experiment"], allow_unicode=True),
                          encoding="utf-8")
    try:
        validate_file(experiment)
    except ExperimentError as exc:
        unlocated = [i for i in exc.issues if i.line is None]
        if unlocated or exc.exit_code != 2:
            return Outcome(case, "unlocated", False, f"{len(unlocated)} unlocated issue(s): "
                           f"{unlocated[0].message[:200] if unlocated else exc}",
                           time.perf_counter() - started)
        return Outcome(case, "refused", True, str(exc.issues[0].message)[:200],
                       time.perf_counter() - started)
    except HapticframeError as exc:
        ok = exc.exit_code == 2
        return Outcome(case, "refused" if ok else "unexpected", ok, str(exc)[:300],
                       time.perf_counter() - started)
    except Exception as exc:  # an internal error at validate
        return Outcome(case, "internal_error", False,
                       f"validate raised {type(exc).__name__}: {exc}"[:300],
                       time.perf_counter() - started)
    why = cannot_have(case.data["device"], case.data["faults"])
    if why is not None:
        return Outcome(case, "accepted_invalid", False, why, time.perf_counter() - started)
    if not run:
        return Outcome(case, "accepted", True, "", time.perf_counter() - started)
    data = copy.deepcopy(case.data["experiment"])
    data.setdefault("run", {}).update({"max_movements": 1, "figures": False})
    experiment.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    out = workdir / "run"
    result = hapticframe_command(["run", str(experiment), "--out", str(out), "--quiet"],
                                 cwd=workdir)
    outcome = classify(case, result, started)
    if outcome.status == "refused":  # the refusal belongs to validate
        return Outcome(case, "unexpected", False, f"refused only at run: {outcome.detail}",
                       outcome.seconds)
    if outcome.status == "ran":
        from hapticframe_bench._fuzz_common import json_has_null_number

        null = json_has_null_number(out / "metrics.json", ("movements",))
        if null:
            return Outcome(case, "null_result", False, null, outcome.seconds)
    return outcome
