"""A lab-local plugin module whose sensor fails on purpose (``--plugin-module lab_faults``).

Registration only: the implementation lives in the sibling module ``lab_faults_impl``, as a
lab keeps its registration and implementation apart; ``--plugin-module lab_faults`` must
resolve it from the same directory.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Literal

from pydantic import Field

from hapticframe import PluginConfig, SensorSpec, hookimpl

Fault = Literal[
    "none", "build-oserror", "build-typeerror", "read-typeerror", "read-interrupt",
    "read-sigterm", "close",
]


class FaultyConfig(PluginConfig):
    fault: Fault = Field("none", description="What goes wrong.")
    reads: int = Field(5, ge=1, description="Reads before the sensor is exhausted.")
    fail_at_read: int = Field(2, ge=1, description="The read that fails (read-* faults).")


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield SensorSpec("lab-faulty", "A sensor that fails on purpose.", FaultyConfig,
                     "lab_faults_impl:FaultySensor", capabilities=frozenset({"finite"}))
