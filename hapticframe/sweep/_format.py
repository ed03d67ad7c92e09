"""How a sweep writes values and tells an unchanged knob (shared by the sweep and its report)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = ["flow_text", "format_value", "unchanged"]


def flow_text(value: Any) -> str:
    """A value as YAML flow text (JSON is YAML), for an override's text and labels."""
    return json.dumps(value, separators=(",", ":"))


def unchanged(points: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> bool:
    """Whether every finished point reports the same accuracy (``keys``) as the first, the
    baseline: the knob bought nothing at the values and seeds tried."""
    done = [p for p in points if p["status"] == "ok"]
    if len(done) < 2 or not keys:
        return False
    first = done[0]["metrics"]
    for p in done[1:]:
        for key in keys:
            a, b = first.get(key), p["metrics"].get(key)
            if a is None and b is None:
                continue
            if a is None or b is None or not math.isclose(float(a), float(b), rel_tol=1e-9,
                                                          abs_tol=1e-12):
                return False
    return True


def format_value(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
