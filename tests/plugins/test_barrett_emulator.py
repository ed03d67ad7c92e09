"""The emulated pucks at the frame level (raw python-can frames), and the host helper on the
real monotonic clock (the emulator's ticking thread, real ``recv`` timeouts; short bounds)."""

from __future__ import annotations

import time
import uuid
from collections.abc import Iterator

import can
import pytest

from hapticframe.devices import FakeClock, MonotonicClock
from hapticframe_barrett import (
    HAND_NODES,
    CanPort,
    EmulatedPuck,
    Group,
    Mode,
    PuckBus,
    PuckHost,
    ReplyTimeout,
    Stat,
    decode_position,
    decode_property_reply,
    encode_get,
    encode_set,
    group_id,
    hand_pucks,
    node_id,
    property_table,
    wam_pucks,
)

TABLE = property_table(160)


@pytest.fixture
def channel() -> str:
    return f"barrett-{uuid.uuid4().hex}"


@pytest.fixture
def raw(channel: str) -> Iterator[can.BusABC]:
    bus = can.Bus(interface="virtual", channel=channel)
    yield bus
    bus.shutdown()


def request(bus: can.BusABC, clock: FakeClock, arbitration_id: int, data: bytes) -> list:
    """Send one frame, let the emulator handle it (clock.sleep(0) syncs), take the replies."""
    bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False))
    clock.sleep(0.0)
    out = []
    while (msg := bus.recv(0.0)) is not None:
        out.append(msg)
    return out


def test_pucks_in_reset_answer_only_stat_and_vers(channel, raw):
    clock = FakeClock()
    with PuckBus(channel, hand_pucks(), clock=clock, wake_delay_s=0.2) as emulator:
        (reply,) = request(raw, clock, node_id(0, 11), encode_get(TABLE["STAT"]))
        assert reply.arbitration_id == group_id(11, Group.PROPERTY) == 0x566
        assert decode_property_reply(reply.data).value == Stat.RESET
        (reply,) = request(raw, clock, node_id(0, 11), encode_get(TABLE["VERS"]))
        assert decode_property_reply(reply.data).value == 160
        assert request(raw, clock, node_id(0, 11), encode_get(TABLE["MODE"])) == []
        assert request(raw, clock, group_id(0, Group.HAND), encode_get(TABLE["P"])) == []
        # Wake the whole hand with one group SET; READY after the wake delay.
        assert request(raw, clock, group_id(0, Group.HAND), encode_set(TABLE["STAT"], 2)) == []
        clock.advance(0.1)
        (reply,) = request(raw, clock, node_id(0, 12), encode_get(TABLE["STAT"]))
        assert decode_property_reply(reply.data).value == Stat.RESET
        clock.advance(0.1)
        (reply,) = request(raw, clock, node_id(0, 12), encode_get(TABLE["STAT"]))
        assert decode_property_reply(reply.data).value == Stat.READY
        replies = request(raw, clock, group_id(0, Group.HAND), encode_get(TABLE["P"]))
        assert sorted(m.arbitration_id for m in replies) == [
            group_id(n, Group.POSITION) for n in HAND_NODES
        ]
        lengths = {m.arbitration_id: len(m.data) for m in replies}
        assert lengths[group_id(11, Group.POSITION)] == 6  # a finger: secondary encoder
        assert lengths[group_id(14, Group.POSITION)] == 3  # the spread
        assert all(decode_position(m.data)[0] == 20_000 for m in replies)
        assert emulator.errors == [] and emulator.notifier_exception is None


def test_four_byte_replies_and_position_wrap(channel, raw):
    clock = FakeClock()
    pucks = [EmulatedPuck(1, hand=False, reply_length=4, position=2**21 + 5)]
    with PuckBus(channel, pucks, clock=clock) as emulator:
        request(raw, clock, node_id(0, 1), encode_set(TABLE["STAT"], 2))
        clock.advance(1.0)
        (reply,) = request(raw, clock, node_id(0, 1), encode_get(TABLE["TEMP"]))
        assert len(reply.data) == 4 and decode_property_reply(reply.data).value == 30
        (reply,) = request(raw, clock, node_id(0, 1), encode_get(TABLE["P"]))
        assert decode_position(reply.data) == (-(2**21) + 5, None)  # the 22-bit counter wraps
        # Setting MODE on an arm puck is the safety system's job: the emulator counts it.
        request(raw, clock, node_id(0, 1), encode_set(TABLE["MODE"], Mode.PID))
        assert emulator.stats["mode_set_on_arm"] == 1


def test_host_on_the_monotonic_clock(channel, raw):
    clock = MonotonicClock()
    pucks = [*hand_pucks(speed=1e6, start=1_000)[:2], *wam_pucks(n=1)]
    with PuckBus(channel, pucks, clock=clock, wake_delay_s=0.01) as emulator:
        host = PuckHost(raw, port=CanPort("virtual", channel, clock=clock), reply_timeout_s=0.3,
                        wake_time_s=0.05)
        woke = host.wake((1, 11, 12, 13), attempts=1)
        assert woke.awake == (1, 11, 12) and woke.failed == (13,)  # 13 is not on the bus
        host.identify((1, 11, 12))
        poll = host.poll_positions(Group.ALL, (1, 11, 12))
        assert poll.complete and poll.positions == {1: 0, 11: 1_000, 12: 1_000}
        host.set(11, "CMD", 13)  # HI: home at a million counts per second
        deadline = time.monotonic() + 1.0
        while host.get(11, "MODE") != Mode.IDLE and time.monotonic() < deadline:
            clock.sleep(0.01)
        assert host.poll_positions(Group.HAND, (11, 12)).positions[11] == 0
        with pytest.raises(ReplyTimeout):
            host.get(13, "VERS", timeout_s=0.1, attempts=1)
        assert host.health.timeouts == 2
        assert emulator.errors == [] and emulator.notifier_exception is None
