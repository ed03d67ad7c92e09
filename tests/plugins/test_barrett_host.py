"""The host helper against the emulated pucks on python-can's virtual bus, fault by fault.

Every wait is on a PacedCanPort's FakeClock; real time is spent only where python-can's
reader thread delivers frames (``settle_s`` per wait that ends without its reply)."""

from __future__ import annotations

import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import can
import numpy as np
import pytest

from hapticframe.devices import FakeClock, FaultEvent, FaultSchedule
from hapticframe_barrett import (
    HAND_NODES,
    WAM_NODES,
    BarrettError,
    BarrettHandHost,
    EmulatedPuck,
    Group,
    MalformedReply,
    Mode,
    PacedCanPort,
    PuckBus,
    PuckHost,
    ReplyTimeout,
    Stat,
    hand_pucks,
    wam_pucks,
)

SETTLE_S = 0.0  # the emulator answers synchronously on clock advances


@dataclass
class Rig:
    clock: FakeClock
    emulator: PuckBus
    bus: can.BusABC
    host: PuckHost
    faults: FaultSchedule

    @property
    def hand(self) -> BarrettHandHost:
        return BarrettHandHost(self.host)


@pytest.fixture
def rig() -> Iterator:
    made: list[Rig] = []

    def make(pucks: Sequence[EmulatedPuck] | None = None, events: Sequence[FaultEvent] = (),
             seed: int = 0, **host_kw: Any) -> Rig:
        channel = f"barrett-{uuid.uuid4().hex}"
        clock = FakeClock()
        faults = FaultSchedule(list(events), np.random.default_rng(seed))
        emulator = PuckBus(channel, hand_pucks() if pucks is None else pucks, clock=clock,
                           faults=faults).start()
        bus = can.Bus(interface="virtual", channel=channel)
        host = PuckHost(bus, port=PacedCanPort(clock, settle_s=SETTLE_S), **host_kw)
        made.append(Rig(clock, emulator, bus, host, faults))
        return made[-1]

    yield make
    for r in made:
        assert r.emulator.errors == []
        assert r.emulator.notifier_exception is None
        r.emulator.stop()
        r.bus.shutdown()


def test_healthy_hand_initialise_close_open_and_poll(rig):
    r = rig()
    hand = r.hand
    hand.initialize()
    assert set(r.host.tables) == set(HAND_NODES)
    assert all(r.emulator.puck(n).counts() == 0 for n in HAND_NODES)
    modes = hand.close()
    assert modes == {11: Mode.IDLE, 12: Mode.IDLE, 13: Mode.IDLE}
    poll = r.host.poll_positions(Group.HAND, HAND_NODES)
    assert poll.complete and poll.positions == {11: 195_000, 12: 195_000, 13: 195_000, 14: 0}
    assert poll.secondary == {11: 195_000, 12: 195_000, 13: 195_000}  # 6-byte replies
    hand.open()
    result = hand.move_to({11: 40_000, 14: 20_000})
    assert result.ok and result.stopped_early == ()
    assert result.poll.positions[11] == 40_000 and result.poll.positions[14] == 20_000
    # 195000 counts at 50000 counts/s: motion advanced only with the fake clock.
    assert 3.9 < r.clock.now() < 20
    assert r.host.health.faults() == {} and r.host.health.frames > 0
    assert r.emulator.stats["ignored"] == 0


def test_motion_follows_only_the_clock(rig):
    r = rig()
    r.hand.initialize()
    r.host.set(11, "M", 100_000)
    before = r.emulator.puck(11).counts()
    assert before == 0 and r.host.get(11, "MODE") == Mode.TRAPEZOIDAL
    r.clock.advance(1.0)
    assert r.host.poll_positions(Group.HAND, HAND_NODES).positions[11] == 50_000
    assert r.host.get(11, "MODE") == Mode.TRAPEZOIDAL
    r.clock.advance(1.0)
    assert r.host.get(11, "MODE") == Mode.IDLE


def test_hold_ends_a_move_in_pid_and_counts_as_done(rig):
    r = rig()
    hand = r.hand
    hand.initialize()
    r.host.set(12, "HOLD", 1)
    hand.hold[12] = r.host.get(12, "HOLD")
    result = hand.move_to({12: 30_000})
    assert result.modes == {12: Mode.PID} and result.ok


def test_puck_that_never_wakes_is_reported_bounded(rig):
    r = rig(events=[FaultEvent("never_wakes", at_s=0.0, params={"node": 13})])
    woke = r.host.wake(HAND_NODES, attempts=2)
    assert woke.awake == (11, 12, 14) and woke.failed == (13,)
    # It answers STAT with RESET (no timeout), and nothing else.
    assert r.host.get(13, "STAT") == Stat.RESET and r.host.health.timeouts == 0
    assert r.clock.now() == pytest.approx(2 * r.host.wake_time_s)
    with pytest.raises(BarrettError, match=r"\[13\] did not wake"):
        BarrettHandHost(r.host).initialize()


def test_absent_puck_times_out_and_is_counted(rig):
    r = rig(events=[FaultEvent("never_wakes", at_s=0.0, params={"node": 14, "absent": 1})])
    woke = r.host.wake(HAND_NODES, attempts=1)
    assert woke.failed == (14,)
    assert r.host.health.timeouts == 1 and r.host.stats["timeouts"] == 1
    start = r.clock.now()
    with pytest.raises(ReplyTimeout, match="puck 14"):
        r.host.get(14, "VERS")
    assert r.host.health.timeouts == 1 + r.host.attempts
    assert r.clock.now() - start == pytest.approx(r.host.attempts * r.host.reply_timeout_s)


def test_puck_gone_after_identify_is_missing_from_polls(rig):
    r = rig(events=[FaultEvent("never_wakes", at_s=5.0, params={"node": 14, "absent": 1})])
    r.hand.initialize()
    assert r.clock.now() < 5.0
    r.clock.advance_to(5.5)
    poll = r.host.poll_positions(Group.HAND, HAND_NODES)
    assert poll.missing == (14,) and 14 not in poll.positions
    assert r.host.health.dropped_samples == 1 and r.host.health.timeouts == 0


def test_late_reply_times_out_is_retried_and_never_taken_as_fresh(rig):
    r = rig(events=[FaultEvent("late_reply", at_s=1.2, params={"delay_s": 1.5, "node": 11})])
    hand = r.hand
    hand.initialize()  # a MODE poll of 11 while homing is answered late: timeout, retry
    assert r.emulator.stats["late"] == 1
    assert r.host.health.timeouts == 1
    # The late frame came after its wait and was discarded before a later request.
    r.clock.advance(2.0)
    assert r.host.get(11, "MODE") == Mode.IDLE
    assert r.host.health.resyncs == 1 and r.host.stats["stale"] == 1


def test_late_mode_reply_during_motion_does_not_end_or_prolong_the_wait(rig):
    r = rig()
    hand = r.hand
    hand.initialize()
    # A MODE reply (TRAPEZOIDAL) sent late arrives after the move has ended: discarded.
    late = FaultEvent("late_reply", at_s=r.clock.now(), params={"delay_s": 0.5, "node": 11})
    r.emulator.faults = FaultSchedule([late], np.random.default_rng(1))
    result = hand.move_to({11: 60_000}, timeout_s=5.0)
    assert result.ok and result.modes[11] == Mode.IDLE
    assert r.host.health.timeouts == 1
    r.host.get(11, "MODE")
    assert r.host.health.resyncs == 1


@pytest.mark.parametrize("how", ["bit7", "byte1", "short"])
def test_malformed_reply_is_counted_and_retried(rig, how):
    r = rig(events=[FaultEvent("malformed_reply", at_s=1.5, params={"how": how, "node": 12})])
    r.host.wake(HAND_NODES)
    r.clock.advance_to(1.5)
    tables = r.host.identify(HAND_NODES)  # puck 12's VERS: malformed once, then good
    assert tables[12].vers == 160
    assert r.host.health.invalid_samples == 1 and r.host.stats["malformed"] == 1
    assert r.host.health.timeouts == 0


def test_malformed_reply_on_every_attempt_raises(rig):
    events = [FaultEvent("malformed_reply", at_s=1.5, params={"how": "bit7"}) for _ in range(2)]
    r = rig(events=events)
    r.host.wake((11,))
    r.clock.advance_to(1.5)
    with pytest.raises(MalformedReply, match="bit 7"):
        r.host.get(11, "VERS")
    assert r.host.health.invalid_samples == 2


def test_reply_with_the_wrong_property_is_not_accepted(rig):
    r = rig(events=[FaultEvent("malformed_reply", at_s=1.5, params={"how": "wrong_property"})])
    r.host.wake((11,))
    r.clock.advance_to(1.5)
    assert r.host.get(11, "VERS") == 160
    assert r.host.health.resyncs == 1 and r.host.health.timeouts == 1


def test_duplicate_replies_are_discarded_as_stale(rig):
    r = rig(events=[FaultEvent("duplicate_reply", at_s=1.5, params={"count": 5})])
    r.host.wake(HAND_NODES)
    r.clock.advance_to(1.5)
    r.host.identify(HAND_NODES)
    assert r.emulator.stats["duplicates"] == 5
    assert r.host.health.resyncs == 5 and r.host.health.timeouts == 0
    assert all(t.vers == 160 for t in r.host.tables.values())


def test_flood_is_bounded(rig):
    r = rig(events=[FaultEvent("duplicate_reply", at_s=0.0, params={"count": 40})],
            max_frames_per_wait=16)
    r.host.wake((11,))
    r.host.identify((11,))
    assert r.host.health.overflows >= 1


def test_missing_position_reply_is_reported_never_stale(rig):
    r = rig(events=[FaultEvent("missing_position", at_s=3.0, params={"node": 12})])
    hand = r.hand
    hand.initialize()
    r.host.set(12, "M", 150_000)
    r.clock.advance(1.0)
    first = r.host.poll_positions(Group.HAND, HAND_NODES)  # before the fault
    assert first.complete
    r.clock.advance(1.0)
    second = r.host.poll_positions(Group.HAND, HAND_NODES)
    assert second.missing == (12,) and 12 not in second.positions and 12 not in second.secondary
    assert r.host.health.dropped_samples == 1
    third = r.host.poll_positions(Group.HAND, HAND_NODES)
    assert third.complete and third.positions[12] == r.emulator.puck(12).counts()
    assert third.positions[12] != first.positions[12]


def test_estop_mid_motion_is_seen_as_mode_idle(rig):
    r = rig()
    hand = r.hand
    hand.initialize()
    t0 = r.clock.now()
    r.emulator.faults = FaultSchedule([FaultEvent("estop", at_s=t0 + 1.0)],
                                      np.random.default_rng(0))
    result = hand.move_to({11: 150_000, 12: 150_000, 13: 150_000}, timeout_s=10.0)
    assert r.emulator.stats["estops"] == 1
    assert result.modes == {11: Mode.IDLE, 12: Mode.IDLE, 13: Mode.IDLE}
    assert not result.ok and result.stopped_early == (11, 12, 13)
    for node in (11, 12, 13):
        assert 45_000 <= result.poll.positions[node] <= 55_000  # stopped where it was at 1 s
    assert r.clock.now() - t0 < 1.5  # the wait ended at the E-stop, not at the timeout


def test_move_that_does_not_end_raises_in_bounded_time(rig):
    r = rig(pucks=hand_pucks(speed=1_000.0, start=0))
    hand = r.hand
    hand.initialize(timeout_s=60.0)
    t0 = r.clock.now()
    with pytest.raises(BarrettError, match="still moving"):
        hand.move_to({11: 150_000}, timeout_s=2.0)
    assert r.clock.now() - t0 == pytest.approx(2.0, abs=0.1)


def test_error_frames_are_counted_and_survived(rig):
    r = rig(events=[FaultEvent("error_frame", at_s=0.5, params={"count": 3})])
    r.hand.initialize()
    assert r.host.health.crc_errors == 3 and r.host.stats["error_frames"] == 3
    assert r.host.poll_positions(Group.HAND, HAND_NODES).complete
    assert r.host.health.timeouts == 0


def test_bus_off_requests_time_out_then_recover(rig):
    r = rig(events=[FaultEvent("bus_off", at_s=2.0, duration_s=0.5)])
    hand = r.hand
    hand.initialize()
    r.clock.advance_to(2.0)
    poll = r.host.poll_positions(Group.HAND, HAND_NODES)
    assert r.host.bus_off and poll.missing == HAND_NODES
    assert r.host.try_get(11, "MODE") is None
    assert r.host.health.stalls == 1 and r.host.health.timeouts == r.host.attempts
    r.clock.advance_to(2.6)
    assert r.host.poll_positions(Group.HAND, HAND_NODES).complete
    assert not r.host.bus_off and r.host.health.reconnects == 1


def test_emulator_gone_is_bounded_and_host_bus_closed_raises(rig):
    r = rig()
    r.hand.initialize()
    r.emulator.stop()  # the pucks' side of the bus shut down
    t0 = r.clock.now()
    with pytest.raises(ReplyTimeout):
        r.host.get(11, "MODE")
    assert r.clock.now() - t0 == pytest.approx(r.host.attempts * r.host.reply_timeout_s)
    r.bus.shutdown()
    with pytest.raises(BarrettError, match=r"CAN (send|receive) failed"):
        r.host.get(11, "MODE")


def test_unsupported_firmware_is_refused(rig):
    r = rig(pucks=[EmulatedPuck(11, vers=200)])
    r.emulator.pucks[11].vers = 60  # answers VERS 60: a table this package does not have
    r.host.wake((11,))
    with pytest.raises(BarrettError, match="VERS 60"):
        r.host.identify((11,))
    with pytest.raises(BarrettError, match="identify"):
        r.host.get(11, "MODE")


def test_wam_positions_follow_targets_only_when_the_safety_system_activates(rig):
    r = rig(pucks=wam_pucks())
    host = r.host
    assert host.wake(WAM_NODES).ok
    host.identify(WAM_NODES)
    poll = host.poll_positions(Group.WAM, WAM_NODES)
    assert poll.complete and poll.positions == dict.fromkeys(WAM_NODES, 0)
    assert poll.secondary == {}  # 3-byte replies
    host.set(3, "M", 10_000)
    r.clock.advance(1.0)
    assert host.poll_positions(Group.WAM, WAM_NODES).positions[3] == 0  # IDLE: ignored
    r.emulator.activate_wam()
    assert host.get(3, "MODE") == Mode.PID
    host.set(3, "M", 10_000)
    host.set(5, "M", -4_000)
    r.clock.advance(0.25)
    poll = host.poll_positions(Group.WAM, WAM_NODES)
    assert poll.positions[3] == 5_000 and poll.positions[5] == -4_000
    assert r.emulator.stats["mode_set_on_arm"] == 0  # the helper never set MODE on the arm
    r.emulator.estop()
    assert all(host.get(n, "MODE") == Mode.IDLE for n in WAM_NODES)
    assert host.health.faults() == {}


def test_random_faults_replay_and_polls_are_always_fresh(rig):
    events = [
        FaultEvent("missing_position", rate_hz=2.0),
        FaultEvent("error_frame", rate_hz=1.0),
        FaultEvent("duplicate_reply", rate_hz=1.0, params={"count": 2}),
        FaultEvent("malformed_reply", rate_hz=1.0, params={"how": "byte1"}),
    ]
    logs = []
    for _ in range(2):
        r = rig(pucks=wam_pucks(), events=events, seed=7)
        host = r.host
        host.wake(WAM_NODES)
        host.identify(WAM_NODES)
        r.emulator.activate_wam()
        for node in WAM_NODES:
            host.set(node, "M", 1_000 * node)
        missing = 0
        for _ in range(40):
            r.clock.advance(0.05)
            poll = host.poll_positions(Group.WAM, WAM_NODES)
            for node, counts in poll.positions.items():
                assert counts == r.emulator.puck(node).counts()  # fresh, never carried over
            missing += len(poll.missing)
            host.try_get(1, "TEMP")
        assert missing == r.faults.count("missing_position") > 0
        assert host.health.dropped_samples == missing
        assert host.health.crc_errors == r.faults.count("error_frame") > 0
        assert host.health.invalid_samples == r.faults.count("malformed_reply")
        logs.append([(f.kind, f.time_s) for f in r.faults.injected])
    assert logs[0] == logs[1]
