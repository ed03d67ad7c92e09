"""DeviceLifecycle transitions and bounded recovery; DeviceHealth counters."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe.devices import (
    Backoff,
    DeviceError,
    DeviceHealth,
    DeviceLifecycle,
    DeviceModel,
    EmulatedTransport,
    FakeClock,
    FaultEvent,
    FaultSchedule,
    LifecycleState,
    LineFramer,
    ParserStats,
    TransportError,
)


class Counter(DeviceModel):
    """Streams a line with a counter every 10 ms while 'powered'."""

    def __init__(self) -> None:
        self.t0: float | None = None
        self.sent = 0

    def receive(self, data: bytes, now_s: float) -> None:
        pass

    def emit(self, now_s: float) -> bytes:
        if self.t0 is None:
            self.t0 = now_s
        due = int((now_s - self.t0) / 0.01) + 1
        out = b"".join(b"%d\n" % k for k in range(self.sent, due))
        self.sent = max(self.sent, due)
        return out


class Driver(DeviceLifecycle):
    """A toy driver: recovers by reopening the transport, with backoff on its clock."""

    max_recoveries = 2

    def __init__(self, clock: FakeClock, faults: FaultSchedule | None = None) -> None:
        self.id = "toy"
        self.clock = clock
        self.transport = EmulatedTransport(Counter(), clock, faults)
        self.framer = LineFramer()
        self.calls: list[str] = []
        self.backoff = Backoff(0.01, 2.0, 0.1, attempts=3)

    def on_configure(self) -> None:
        self.calls.append("configure")

    def on_activate(self) -> None:
        self.calls.append("activate")
        self.transport.open()

    def on_deactivate(self) -> None:
        self.calls.append("deactivate")
        self.transport.close()

    def on_cleanup(self) -> None:
        self.calls.append("cleanup")

    def on_recover(self, error: Exception) -> None:
        self.calls.append("recover")
        self.transport.close()
        for delay in self.backoff:  # bounded: a few reopen attempts
            self.clock.sleep(delay)
            try:
                self.transport.open()
            except TransportError:
                continue  # still unplugged
            self.clock.sleep(0.02)
            if self.transport.read_available():
                self.health.reconnects += 1
                return
        raise TransportError("no data after reopening")

    def read(self) -> list[bytes]:
        try:
            data = self.transport.read_available()
        except TransportError as exc:
            self.recover(exc)
            return []
        lines = self.framer.feed(data)
        self.health.add_parser(self.framer.stats)
        return lines


def test_transitions_in_order_and_checked():
    driver = Driver(FakeClock())
    assert driver.lifecycle_state is LifecycleState.UNCONFIGURED
    with pytest.raises(DeviceError, match=r"'toy'.*configure it first"):
        driver.activate()
    driver.configure()
    driver.configure()  # again: a no-op
    assert driver.lifecycle_state is LifecycleState.INACTIVE
    driver.activate()
    assert driver.lifecycle_state is LifecycleState.ACTIVE and driver.transport.is_open
    driver.deactivate()
    driver.deactivate()
    driver.cleanup()
    driver.cleanup()
    assert driver.lifecycle_state is LifecycleState.FINALIZED
    assert driver.calls == ["configure", "activate", "deactivate", "cleanup"]
    assert not driver.live


def test_cleanup_of_an_active_device_deactivates_it_and_never_raises_for_a_gone_link():
    driver = Driver(FakeClock())

    def gone() -> None:
        raise TransportError("write failed: [Errno 5] Input/output error")

    driver.on_deactivate = gone  # type: ignore[method-assign]
    driver.configure()
    driver.activate()
    driver.cleanup()  # the device was unplugged: stopping it fails quietly
    assert driver.lifecycle_state is LifecycleState.FINALIZED
    driver.configure()  # a cleaned-up device can start again
    assert driver.lifecycle_state is LifecycleState.INACTIVE


def test_a_failed_activation_is_a_device_error_naming_the_device():
    driver = Driver(FakeClock())

    def no_port() -> None:
        raise TransportError("cannot open /dev/ttyUSB9: no such file")

    driver.on_activate = no_port  # type: ignore[method-assign]
    driver.configure()
    with pytest.raises(DeviceError, match="'toy': activate failed: cannot open /dev/ttyUSB9"):
        driver.activate()
    assert driver.lifecycle_state is LifecycleState.ERROR
    with pytest.raises(DeviceError, match="ERROR"):
        driver.configure()
    driver.cleanup()
    assert driver.lifecycle_state is LifecycleState.FINALIZED


def test_a_device_that_comes_back_is_recovered_and_counted():
    clock = FakeClock()
    unplug = FaultEvent("disconnect", at_s=0.055, duration_s=0.02)
    driver = Driver(clock, FaultSchedule([unplug], np.random.default_rng(0)))
    driver.configure()
    driver.activate()
    lines = []
    for _ in range(5):
        clock.sleep(0.01)
        lines += driver.read()
    clock.sleep(0.01)
    assert driver.read() == []  # unplugged: recovered by reopening after 10 + 20 ms
    assert driver.health.recoveries == 1 and driver.health.reconnects == 1
    assert driver.recovery_streak == 0 and driver.lifecycle_state is LifecycleState.ACTIVE
    clock.sleep(0.01)
    assert driver.read()  # data flows again
    assert driver.health.frames >= len(lines) > 0


def test_recovery_is_bounded():
    clock = FakeClock()
    unplug = FaultEvent("disconnect", at_s=0.005, duration_s=100.0)
    driver = Driver(clock, FaultSchedule([unplug], np.random.default_rng(0)))
    driver.configure()
    driver.activate()
    clock.sleep(0.01)
    started = clock.now()
    with pytest.raises(DeviceError, match="'toy' did not recover after 2 attempts"):
        driver.read()
    assert driver.health.recoveries == 2
    assert driver.calls.count("recover") == 2
    assert driver.lifecycle_state is LifecycleState.ERROR
    assert driver.calls[-1] == "deactivate" and not driver.transport.is_open
    # Bounded in time too: two attempts of three backoff delays each.
    assert clock.now() - started == pytest.approx(2 * (0.01 + 0.02 + 0.04))
    with pytest.raises(DeviceError, match="cannot recover from error"):
        driver.recover(RuntimeError("again"))
    driver.deactivate()  # idempotent in ERROR too
    driver.cleanup()


def test_health_counters_and_parser_deltas():
    health = DeviceHealth()
    stats = ParserStats(bytes=100, frames=5, crc_errors=1, resyncs=3)
    health.add_parser(stats)
    stats.bytes, stats.frames = 180, 10
    health.add_parser(stats)
    assert (health.bytes, health.frames, health.crc_errors, health.resyncs) == (180, 10, 1, 3)
    # A new parser (after a reconnect) counts from zero.
    health.add_parser(ParserStats(bytes=16, frames=1))
    assert health.bytes == 196 and health.frames == 11
    health.timeouts += 2
    assert health.faults() == {"crc_errors": 1, "resyncs": 3, "timeouts": 2}
    counters = health.as_dict()
    assert counters["bytes"] == 196 and counters["recoveries"] == 0
    assert set(counters) >= {"bytes", "frames", "crc_errors", "resyncs", "timeouts", "stalls",
                             "reconnects", "dropped_samples", "invalid_samples", "recoveries"}
    assert all(isinstance(v, int) for v in counters.values())
