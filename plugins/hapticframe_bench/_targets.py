"""Targets of the benchmark suites, each printed beside its measurement with a verdict.

Every suite states its targets as :class:`Target` records; :func:`check_targets` measures
each against the suite's results and gives the lines a suite prints
(``update 3000 obs: 41 ms  (target <= 50 ms)  met``) and the records it writes to its JSON
(``"targets"``: name → value, limit, unit, comparison, met) and markdown.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = ["Target", "TargetCheck", "check_lines", "check_targets", "load_average",
           "load_note", "record_rows", "targets_markdown"]


@dataclass(frozen=True)
class Target:
    """One figure a suite promises.

    Parameters
    ----------
    name : str
        Key of the measured value in the suite's results (also the key in ``"targets"``).
    label : str
        What is measured, for people (``"update 200 points"``).
    limit : float
        The target value.
    unit : str
        Unit of the value and the limit (``"ms"``, ``"cm"``, ``""``).
    at_most : bool
        True: the value must not exceed ``limit``; False: it must reach it.
    digits : int
        Decimals printed.
    """

    name: str
    label: str
    limit: float
    unit: str = ""
    at_most: bool = True
    digits: int = 1


@dataclass(frozen=True)
class TargetCheck:
    """A target with its measured value and the verdict (``met`` is None when unmeasured)."""

    target: Target
    value: float | None
    met: bool | None

    @property
    def verdict(self) -> str:
        """``"met"``, ``"missed"`` or ``"not measured"``."""
        return "not measured" if self.met is None else ("met" if self.met else "missed")

    def _number(self, value: float) -> str:
        unit = f" {self.target.unit}" if self.target.unit else ""
        return f"{value:.{self.target.digits}f}{unit}"

    def line(self) -> str:
        """``label: value  (target <= limit)  verdict``."""
        target = self.target
        sign = "<=" if target.at_most else ">="
        value = "–" if self.value is None else self._number(self.value)
        return (f"{target.label}: {value}  (target {sign} {self._number(target.limit)})  "
                f"{self.verdict}")

    def as_dict(self) -> dict[str, Any]:
        """The JSON record: value, limit, unit, comparison and whether it was met."""
        return {"label": self.target.label, "value": self.value, "limit": self.target.limit,
                "unit": self.target.unit, "comparison": "<=" if self.target.at_most else ">=",
                "met": self.met}


def _value(results: Mapping[str, Any], name: str) -> float | None:
    value = results.get(name)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def check_targets(targets: Sequence[Target], results: Mapping[str, Any]) -> list[TargetCheck]:
    """Measure each target against ``results[target.name]`` (a missing or non-finite value is
    "not measured", never "met")."""
    checks = []
    for target in targets:
        value = _value(results, target.name)
        met = None if value is None else (value <= target.limit if target.at_most
                                          else value >= target.limit)
        checks.append(TargetCheck(target, value, met))
    return checks


def targets_markdown(checks: Sequence[TargetCheck]) -> list[str]:
    """A markdown table of the checks: target, measured, verdict."""
    lines = ["| figure | measured | target | verdict |", "|---|---|---|---|"]
    for check in checks:
        target = check.target
        sign = "≤" if target.at_most else "≥"
        measured = "–" if check.value is None else check._number(check.value)
        lines.append(f"| {target.label} | {measured} | {sign} {check._number(target.limit)} | "
                     f"{check.verdict} |")
    return lines


def load_average() -> float | None:
    """The 1-minute load average (None where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None


def load_note(load: float | None) -> str:
    """How loaded the machine was, for the reader of a timing: the load beside the CPUs."""
    cpus = os.cpu_count() or 1
    if load is None:
        return f"{cpus} CPUs, load average unknown"
    note = f"load average {load:.1f} on {cpus} CPUs"
    return note + (" (shared: timings are slower than on a quiet machine)" if load > 0.75 * cpus
                   else "")


def _record_text(record: Mapping[str, Any]) -> tuple[str, str, str, str]:
    """Measured, target and verdict of a saved record (``TargetCheck.as_dict``)."""
    unit = f" {record['unit']}" if record.get("unit") else ""
    value = record.get("value")
    measured = "–" if value is None else f"{value:.2f}{unit}"
    met = record.get("met")
    verdict = "not measured" if met is None else ("met" if met else "missed")
    return measured, f"{record['limit']:g}{unit}", record["comparison"], verdict


def check_lines(records: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """The printed lines of saved target records (``label: value  (target <= x)  verdict``)."""
    lines = []
    for record in records.values():
        measured, limit, comparison, verdict = _record_text(record)
        lines.append(f"{record['label']}: {measured}  (target {comparison} {limit})  {verdict}")
    return lines


def record_rows(records: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """A markdown table of saved target records: figure, measured, target, verdict."""
    lines = ["| figure | measured | target | verdict |", "|---|---|---|---|"]
    for record in records.values():
        measured, limit, comparison, verdict = _record_text(record)
        sign = "≤" if comparison == "<=" else "≥"
        lines.append(f"| {record['label']} | {measured} | {sign} {limit} | {verdict} |")
    return lines
