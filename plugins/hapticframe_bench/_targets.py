"""Targets of the benchmark suites, each printed beside its measurement with a verdict.

Every suite states its targets as :class:`Target` records; :func:`check_targets` measures
each against the suite's results and gives the lines a suite prints
(``update 3000 obs: 41 ms  (target <= 50 ms)  met``) and the records it writes to its JSON
(``"targets"``: name → value, limit, unit, comparison, met) and markdown.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

__all__ = ["Target", "TargetCheck", "check_targets", "targets_markdown"]


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
