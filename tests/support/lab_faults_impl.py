"""The implementation of ``lab_faults``'s sensor (a sibling module of the registration)."""

from __future__ import annotations

import os
import signal
from collections.abc import Mapping
from typing import Any

import numpy as np

from hapticframe.kinds import ChannelInfo, SampleBatch, Sensor

#: ("closed", id) for every close, in order: the tests check nothing is left open.
EVENTS: list[tuple[str, str]] = []


class FaultySensor(Sensor):
    def __init__(self, config: Any, context: Any) -> None:
        super().__init__(config, context)
        if config.fault == "build-oserror":
            raise OSError(f"/dev/ttyLAB0 of {context.id} is busy")
        if config.fault == "build-typeerror":
            raise TypeError("unsupported operand type(s) for +: 'int' and 'str'")
        self._reads = 0

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return {"force_n": ChannelInfo((2,), "N", 100.0)}

    @property
    def exhausted(self) -> bool:
        return self._reads >= self.config.reads

    def read(self) -> SampleBatch:
        self._reads += 1
        fault = self.config.fault
        if self._reads == self.config.fail_at_read:
            if fault == "read-typeerror":
                return SampleBatch(None + 1, {})  # type: ignore[operator]  # a plugin's bug
            if fault == "read-interrupt":
                raise KeyboardInterrupt
            if fault == "read-sigterm":
                os.kill(os.getpid(), signal.SIGTERM)
        t = np.array([0.01 * self._reads])
        return SampleBatch(t, {"force_n": np.array([[1.0 * self._reads, 0.0]])})

    def close(self) -> None:
        EVENTS.append(("closed", self.id))
        if self.config.fault == "close":
            raise RuntimeError(f"{self.id}: the port would not close")
