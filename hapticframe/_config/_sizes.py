"""What a setting costs at run time: one mechanism for every field that sizes an allocation
or a loop.

A schema range says what a field may hold, not what the value costs with the rest of the
experiment: ``monte_carlo_samples: 100000`` is legal, and on a 301 x 201 evaluation grid it
asks for 45 GiB. A plugin's validator therefore *declares* each such field by yielding a
:class:`Size` record (whatever the value, so that the conformance kit learns which fields
size what), with its estimate in bytes and in iterations of the loop it sizes; the core
refuses, located at the field, every estimate over :data:`MEMORY_LIMIT_BYTES` or
:data:`ITERATION_LIMIT`, and says the estimate. The kit's ``check_declared_sizes`` sets each
declared field to the extremes of its schema range and checks that each is refused or
estimated, built and run within the limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["ITERATION_LIMIT", "MEMORY_LIMIT_BYTES", "Size", "format_bytes"]

#: The most memory one sized allocation of a component may take: 4 GiB.
MEMORY_LIMIT_BYTES = 4 * 2**30
#: The most iterations one sized loop may run in one call of the component (at a
#: microsecond an iteration, about two minutes of work: more is a loop that never ends).
ITERATION_LIMIT = 10**8

_UNITS = ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB", "ZiB", "YiB")


def format_bytes(count: float) -> str:
    """``count`` bytes in binary units, three significant digits: ``"44.7 GiB"``."""
    if not math.isfinite(count):
        return "unbounded memory"
    value, unit = float(count), 0
    while value >= 1024 and unit < len(_UNITS) - 1:
        value /= 1024
        unit += 1
    return f"{value:.3g} {_UNITS[unit]}"


@dataclass(frozen=True)
class Size:
    """What one config field costs at run time, as a plugin's validator estimates it.

    A validator yields one for every field that sizes an allocation or a loop, whatever its
    value; the core refuses the experiment, at ``field``, when the estimate exceeds
    :data:`MEMORY_LIMIT_BYTES` or :data:`ITERATION_LIMIT`.

    Parameters
    ----------
    field : str
        The dotted config field that sizes it (``"monte_carlo_samples"``).
    what : str
        What is allocated or iterated, with the numbers behind it ("Monte Carlo activations
        of 100000 samples at 60501 grid points").
    bytes : float
        The largest memory it takes at once (an estimate; ``inf`` when unbounded).
    iterations : float
        The iterations of the loop it sizes, in one call of the component.
    remedy : str
        What to change ("increase hinge_spacing_m"); said after the estimate.
    """

    field: str
    what: str
    bytes: float = 0.0
    iterations: float = 0.0
    remedy: str = ""

    def __post_init__(self) -> None:
        if not self.field:
            raise ValueError("a Size names the config field that sizes it")
        for name in ("bytes", "iterations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise TypeError(f"Size.{name} must be a number, got {value!r}")
            if math.isnan(value) or value < 0:
                raise ValueError(f"Size.{name} must be a non-negative number, got {value!r}")

    def problem(
        self, memory_limit: float = MEMORY_LIMIT_BYTES, iteration_limit: float = ITERATION_LIMIT
    ) -> str | None:
        """The message refusing this size, or None when it is within the limits."""
        remedy = f": {self.remedy}" if self.remedy else ""
        if self.bytes > memory_limit:
            return (f"{self.field} asks for about {format_bytes(self.bytes)} ({self.what}); "
                    f"the limit is {format_bytes(memory_limit)}{remedy}")
        if self.iterations > iteration_limit:
            shown = "unbounded" if math.isinf(self.iterations) else f"{self.iterations:.3g}"
            return (f"{self.field} asks for {shown} iterations in one call ({self.what}); "
                    f"the limit is {iteration_limit:.0e}{remedy}")
        return None
