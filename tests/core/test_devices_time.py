"""Clocks, ClockSync, Backoff and fault schedules of hapticframe.devices."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe.devices import (
    Backoff,
    Clock,
    ClockSync,
    FakeClock,
    FaultEvent,
    FaultSchedule,
    MonotonicClock,
)


def test_fake_clock_listeners_see_every_advance():
    clock = FakeClock(10.0)
    seen: list[float] = []
    clock.add_listener(seen.append)
    clock.sleep(0.5)
    clock.advance(0.0)
    clock.advance_to(12.0)
    clock.advance_to(11.0)  # the past: no move, no call
    assert seen == [10.5, 10.5, 12.0] and clock.now() == 12.0
    clock.remove_listener(seen.append)
    clock.advance(1.0)
    assert len(seen) == 3
    clock.remove_listener(seen.append)  # removing twice is harmless
    with pytest.raises(ValueError):
        clock.advance(-0.1)
    assert isinstance(clock, Clock) and isinstance(MonotonicClock(), Clock)


def test_a_listener_may_remove_itself():
    clock = FakeClock()
    calls = []

    def once(now: float) -> None:
        calls.append(now)
        clock.remove_listener(once)

    clock.add_listener(once)
    clock.advance(1.0)
    clock.advance(1.0)
    assert calls == [1.0]


def test_backoff_is_bounded():
    delays = list(Backoff(initial_s=0.05, factor=2.0, max_s=0.3, attempts=6))
    assert delays == pytest.approx([0.05, 0.1, 0.2, 0.3, 0.3, 0.3])
    assert len(Backoff(attempts=4)) == 4 == len(list(Backoff(attempts=4)))
    assert Backoff(0.1, 1.0, 1.0, attempts=3).total_s == pytest.approx(0.3)
    with pytest.raises(ValueError):
        Backoff(attempts=0)


def test_clock_sync_recovers_offset_and_drift():
    rng = np.random.default_rng(4)
    offset, drift, period = 1234.5, 500e-6, 0.01
    sync = ClockSync(period, window=1000)
    errors = []
    for k in range(1000):
        device = k * period
        host = offset + (1 + drift) * device + 0.002 + rng.uniform(0, 0.001)  # latency
        estimate = sync.update(device, host)
        errors.append(estimate - (offset + (1 + drift) * device + 0.002))
    assert sync.drift == pytest.approx(drift, abs=2e-5)
    # The offset includes the least latency seen (2 ms), not the jitter above it.
    assert sync.offset_s == pytest.approx(offset + 0.002, abs=2e-4)
    assert abs(errors[-1]) < 2e-4


def test_clock_sync_estimates_increase_within_a_burst():
    # Five samples read at once: one host time; the estimates keep the device's spacing.
    sync = ClockSync(0.01)
    for k in range(5):
        sync.update(k * 0.01, 5.05)
    times = [sync.host_time(k * 0.01) for k in range(5)]
    assert times == pytest.approx([5.01, 5.02, 5.03, 5.04, 5.05])
    assert sync.drift == 0.0  # a 40 ms span is too short to estimate a drift


def test_clock_sync_counts_gaps_in_times_and_sequences():
    by_time = ClockSync(0.01)
    missed = [by_time.gap(t) for t in (0.0, 0.01, 0.02, 0.05, 0.0601, 0.07)]
    assert missed == [0, 0, 0, 2, 0, 0] and by_time.gaps == 2
    by_seq = ClockSync()
    assert [by_seq.gap(s) for s in (7, 8, 12, 12, 3, 5)] == [0, 0, 3, 0, 0, 1]
    assert by_seq.gaps == 4
    by_seq.reset()
    assert by_seq.gap(100) == 0 and np.isnan(by_seq.offset_s)


def _run(schedule: FaultSchedule, kinds: tuple[str, ...], until_s: float) -> list[tuple]:
    fired = []
    for step in range(int(until_s / 0.01)):
        now = step * 0.01
        for kind in kinds:
            while (event := schedule.fires(kind, now)) is not None:
                fired.append((kind, now, event.params.get("count")))
    return fired


def test_fault_schedule_is_deterministic_per_seed():
    events = [FaultEvent("garbage", rate_hz=5.0, params={"count": 3}),
              FaultEvent("bad_crc", rate_hz=2.0)]
    first = _run(FaultSchedule(events, np.random.default_rng(1)), ("garbage", "bad_crc"), 10)
    again = _run(FaultSchedule(events, np.random.default_rng(1)), ("garbage", "bad_crc"), 10)
    other = _run(FaultSchedule(events, np.random.default_rng(2)), ("garbage", "bad_crc"), 10)
    assert first == again and first != other
    assert 25 <= sum(k == "garbage" for k, *_ in first) <= 80  # Poisson(50)
    # One event's occurrences do not depend on whether another is asked about.
    only = _run(FaultSchedule(events, np.random.default_rng(1)), ("garbage",), 10)
    assert only == [f for f in first if f[0] == "garbage"]


def test_one_shot_fires_once_and_rate_fires_repeatedly():
    schedule = FaultSchedule(
        [FaultEvent("bad_crc", at_s=0.5), FaultEvent("no_reply", rate_hz=20.0)],
        np.random.default_rng(0),
    )
    assert schedule.fires("bad_crc", 0.49) is None
    assert schedule.fires("bad_crc", 0.6) is not None
    assert schedule.fires("bad_crc", 0.7) is None and schedule.fires("bad_crc", 9.0) is None
    assert schedule.fires("unknown_kind", 9.0) is None
    hits = sum(schedule.fires("no_reply", t / 100) is not None for t in range(1000))
    assert 100 <= hits <= 300
    assert schedule.count("bad_crc") == 1 and schedule.count("no_reply") == hits
    assert schedule.injected[0].kind == "bad_crc" and schedule.injected[0].time_s == 0.5


def test_active_holds_for_the_duration():
    schedule = FaultSchedule([FaultEvent("stall", at_s=1.0, duration_s=0.2)],
                             np.random.default_rng(0))
    assert schedule.active("stall", 0.99) is None
    assert schedule.active("stall", 1.0) is not None
    assert schedule.active("stall", 1.19) is not None
    assert schedule.active("stall", 1.2) is None
    assert schedule.count("stall") == 1  # logged once, however often it is seen
    assert "0.2" in schedule.injected[0].detail


def test_from_config_builds_events_and_rejects_unknown_keys():
    schedule = FaultSchedule.from_config(
        [{"kind": "stall", "at_s": 2, "duration_s": 0.1},
         {"kind": "garbage", "rate_hz": 1, "params": {"count": 4}}],
        np.random.default_rng(0),
    )
    assert schedule.events[0] == FaultEvent("stall", at_s=2.0, duration_s=0.1)
    assert schedule.events[1].params == {"count": 4}
    assert schedule.kinds == {"stall", "garbage"}
    with pytest.raises(ValueError, match=r"unknown key.*at_time"):
        FaultSchedule.from_config([{"kind": "stall", "at_time": 1}], np.random.default_rng(0))
    with pytest.raises(ValueError, match="exactly one"):
        FaultSchedule.from_config([{"kind": "stall"}], np.random.default_rng(0))
    with pytest.raises(ValueError, match="kind"):
        FaultSchedule.from_config([{"at_s": 1}], np.random.default_rng(0))
