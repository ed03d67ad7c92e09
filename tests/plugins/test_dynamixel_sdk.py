"""The reference: the real, unmodified ``dynamixel_sdk`` talking to :class:`DynamixelBus`
behind a pseudo-terminal (thread mode, host monotonic clock).

``PortHandler`` opens ``serial.Serial(port=path)`` with a fixed list of baud rates, so the
port is opened at 1 000 000 baud (a pty accepts and ignores any rate). The SDK's reply
timeout is 2 x ``LATENCY_TIMER`` + 2 ms; it is raised here for a loaded machine.
"""

from __future__ import annotations

import termios
import time
from collections.abc import Iterator
from pathlib import Path

import dynamixel_sdk  # type: ignore[import-untyped]
import numpy as np
import pytest
import serial
from dynamixel_sdk import port_handler as sdk_port

from hapticframe.devices import FaultEvent, FaultSchedule, MonotonicClock, PtyEmulator
from hapticframe_dynamixel import (
    ERR_ACCESS,
    ERR_ALERT,
    ERR_DATA_RANGE,
    HW_ERROR_OVERLOAD,
    XM430_W350_MODEL_NUMBER,
    DynamixelBus,
    current_to_amps,
    to_signed,
)

ADDR_TORQUE = 64
ADDR_HW_ERROR = 70
ADDR_GOAL = 116
ADDR_OPERATING_MODE = 11
ADDR_CURRENT = 126
ADDR_POSITION = 132
#: The SDK's timeout becomes 2 x 250 + 2 = 502 ms plus the bytes' time: a reply never times
#: out on a loaded machine (the tests that expect a timeout wait that long).
LATENCY_MS = 250

COMM_SUCCESS = dynamixel_sdk.COMM_SUCCESS
COMM_RX_TIMEOUT = dynamixel_sdk.COMM_RX_TIMEOUT
COMM_RX_CORRUPT = dynamixel_sdk.COMM_RX_CORRUPT


@pytest.fixture(autouse=True)
def _latency(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sdk_port, "LATENCY_TIMER", LATENCY_MS)


class Link:
    def __init__(self, bus: DynamixelBus, faults: FaultSchedule | None = None) -> None:
        self.bus = bus
        self.clock = MonotonicClock()
        self.emulator = PtyEmulator(bus, clock=self.clock, faults=faults)
        self.emulator.start()
        self.port = dynamixel_sdk.PortHandler(self.emulator.path)
        assert self.port.openPort()
        assert self.port.setBaudRate(1_000_000)
        self.ph = dynamixel_sdk.PacketHandler(2.0)

    def close(self) -> None:
        self.port.closePort()
        self.emulator.stop()


def _link(bus: DynamixelBus, faults: FaultSchedule | None = None) -> Iterator[Link]:
    link = Link(bus, faults)
    try:
        yield link
    finally:
        link.close()


@pytest.fixture
def link() -> Iterator[Link]:
    yield from _link(DynamixelBus([1, 2, 3], time_constant_s=0.02))


def _faulty(*events: FaultEvent, ids: tuple[int, ...] = (1, 2, 3)) -> Iterator[Link]:
    faults = FaultSchedule(list(events), np.random.default_rng(0))
    return _link(DynamixelBus(list(ids), faults=faults, time_constant_s=0.02), faults)


def _ok(result: tuple[int, int]) -> None:
    comm, error = result
    assert (comm, error) == (COMM_SUCCESS, 0)


def _position(link: Link, servo_id: int) -> int:
    value, comm, _ = link.ph.read4ByteTxRx(link.port, servo_id, ADDR_POSITION)
    assert comm == COMM_SUCCESS, link.ph.getTxRxResult(comm)
    return to_signed(value, 4)


def test_ping_identifies_the_xm430(link: Link) -> None:
    assert link.ph.ping(link.port, 1) == (XM430_W350_MODEL_NUMBER, COMM_SUCCESS, 0)
    model, comm, _ = link.ph.ping(link.port, 7)
    assert comm == COMM_RX_TIMEOUT
    model, comm, error = link.ph.read2ByteTxRx(link.port, 3, 0)
    assert (model, comm, error) == (1020, COMM_SUCCESS, 0)


def test_torque_goal_and_present_position_converge(link: Link) -> None:
    ph, port = link.ph, link.port
    _ok(ph.write1ByteTxRx(port, 1, ADDR_TORQUE, 1))
    _ok(ph.write4ByteTxRx(port, 1, ADDR_GOAL, 3000))
    deadline = time.monotonic() + 1.0
    position = _position(link, 1)
    while abs(position - 3000) > 2 and time.monotonic() < deadline:
        time.sleep(0.02)
        position = _position(link, 1)
    assert abs(position - 3000) <= 2
    assert link.bus.servo(2).get("Present Position") == 2048  # the others did not move


def test_group_sync_write_and_read_three_servos(link: Link) -> None:
    ph, port = link.ph, link.port
    for servo_id in (1, 2, 3):
        _ok(ph.write1ByteTxRx(port, servo_id, ADDR_TORQUE, 1))
    goals = {1: 1000, 2: 2500, 3: 4000}
    writer = dynamixel_sdk.GroupSyncWrite(port, ph, ADDR_GOAL, 4)
    for servo_id, goal in goals.items():
        assert writer.addParam(servo_id, list(goal.to_bytes(4, "little")))
    assert writer.txPacket() == COMM_SUCCESS
    reader = dynamixel_sdk.GroupSyncRead(port, ph, ADDR_CURRENT, 10)  # current..position
    for servo_id in goals:
        assert reader.addParam(servo_id)
    deadline = time.monotonic() + 1.0
    while True:
        assert reader.txRxPacket() == COMM_SUCCESS
        positions = {
            i: to_signed(reader.getData(i, ADDR_POSITION, 4), 4) for i in goals
        }
        if all(abs(positions[i] - goals[i]) <= 2 for i in goals):
            break
        assert time.monotonic() < deadline, positions
        time.sleep(0.02)
    assert all(reader.isAvailable(i, ADDR_CURRENT, 2) for i in goals)
    assert current_to_amps(reader.getData(1, ADDR_CURRENT, 2)) == 0.0


def test_eeprom_write_with_torque_on_is_an_access_error(link: Link) -> None:
    ph, port = link.ph, link.port
    _ok(ph.write1ByteTxRx(port, 2, ADDR_OPERATING_MODE, 4))  # torque off: allowed
    _ok(ph.write1ByteTxRx(port, 2, ADDR_TORQUE, 1))
    comm, error = ph.write1ByteTxRx(port, 2, ADDR_OPERATING_MODE, 3)
    assert comm == COMM_SUCCESS and error == ERR_ACCESS
    assert "not available" in ph.getRxPacketError(error)
    assert link.bus.servo(2).get("Operating Mode") == 4


def test_goal_outside_the_position_limits_is_a_data_range_error(link: Link) -> None:
    ph, port = link.ph, link.port
    _ok(ph.write1ByteTxRx(port, 1, ADDR_TORQUE, 1))
    comm, error = ph.write4ByteTxRx(port, 1, ADDR_GOAL, 5000)
    assert (comm, error) == (COMM_SUCCESS, ERR_DATA_RANGE)
    assert link.bus.servo(1).get("Goal Position") == 2048


def test_overload_sets_the_alert_bit_and_torque_off_until_reboot(link: Link) -> None:
    ph, port = link.ph, link.port
    _ok(ph.write1ByteTxRx(port, 3, ADDR_TORQUE, 1))
    link.bus.set_load(3, lambda t: -0.5)  # N·m: within the limit, a negative current
    time.sleep(0.01)
    raw, comm, error = ph.read2ByteTxRx(port, 3, ADDR_CURRENT)
    assert comm == COMM_SUCCESS and error == 0
    assert raw > 32767  # the SDK returns it unsigned
    assert current_to_amps(raw) == pytest.approx(-0.5 / 1.78, abs=3e-3)
    link.bus.set_load(3, lambda t: 9.0)  # far beyond the current limit (3.2 A)
    deadline = time.monotonic() + 1.0
    while not link.bus.servo(3).hardware_error and time.monotonic() < deadline:
        time.sleep(0.005)
    value, comm, error = ph.read1ByteTxRx(port, 3, ADDR_HW_ERROR)
    assert comm == COMM_SUCCESS and error == ERR_ALERT
    assert value & HW_ERROR_OVERLOAD
    torque, _, error = ph.read1ByteTxRx(port, 3, ADDR_TORQUE)
    assert torque == 0 and error & ERR_ALERT
    comm, error = ph.write1ByteTxRx(port, 3, ADDR_TORQUE, 1)  # refused while latched
    assert comm == COMM_SUCCESS and error & ERR_ALERT and error & 0x7F
    link.bus.set_load(3, None)
    comm, error = ph.reboot(port, 3)
    assert comm == COMM_SUCCESS
    time.sleep(0.005)
    value, comm, error = ph.read1ByteTxRx(port, 3, ADDR_HW_ERROR)
    assert (value, comm, error) == (0, COMM_SUCCESS, 0)
    _ok(ph.write1ByteTxRx(port, 3, ADDR_TORQUE, 1))


def test_a_missing_servo_fails_the_sync_read_as_the_sdk_does() -> None:
    for link in _faulty(FaultEvent("sync_missing", at_s=0.0, params={"id": 2})):
        reader = dynamixel_sdk.GroupSyncRead(link.port, link.ph, ADDR_POSITION, 4)
        for servo_id in (1, 2, 3):
            reader.addParam(servo_id)
        # Servo 1 answers; waiting for 2 the SDK reads 3's status, skips it, and times out.
        assert reader.txRxPacket() in (COMM_RX_TIMEOUT, COMM_RX_CORRUPT)
        assert not reader.isAvailable(1, ADDR_POSITION, 4)
        assert reader.txRxPacket() == COMM_SUCCESS  # the next one is whole
        assert [s.fault for s in link.bus.sent if s.fault] == ["sync_missing"]


def test_status_faults_reach_the_sdk_as_on_a_real_bus() -> None:
    events = (
        FaultEvent("bad_crc", at_s=0.0, params={"id": 1}),
        FaultEvent("error_code", at_s=0.0, params={"id": 2, "error": 6}),
        FaultEvent("junk", at_s=0.0, params={"id": 3, "count": 7}),
        FaultEvent("no_reply", at_s=0.0, params={"id": 3}),
    )
    for link in _faulty(*events):
        ph, port = link.ph, link.port
        assert ph.ping(port, 1)[1] == COMM_RX_CORRUPT
        assert ph.ping(port, 1) == (1020, COMM_SUCCESS, 0)
        # An error status carries no data (read1Byte then returns the CRC's low byte).
        _, comm, error = ph.read1ByteTxRx(port, 2, ADDR_TORQUE)
        assert (comm, error) == (COMM_SUCCESS, 6)
        assert ph.ping(port, 3)[1] == COMM_RX_TIMEOUT  # no_reply comes first for servo 3
        assert ph.ping(port, 3) == (1020, COMM_SUCCESS, 0)  # junk before it: skipped
        assert sorted(s.fault for s in link.bus.sent if s.fault) == [
            "bad_crc", "error_code", "junk", "no_reply",
        ]


def test_late_reply_and_late_duplicate() -> None:
    events = (
        FaultEvent("late_reply", at_s=0.0, params={"id": 1, "delay_s": 0.8}),
        FaultEvent("late_duplicate", at_s=0.0, params={"id": 2}),
        FaultEvent("late_duplicate", at_s=0.0, params={"id": 3}),
    )
    for link in _faulty(*events):
        ph, port = link.ph, link.port
        assert ph.ping(port, 1)[1] == COMM_RX_TIMEOUT
        time.sleep(0.4)  # the late reply (0.8 s, after the 0.5 s timeout) arrives; the next
        # request flushes it
        assert ph.ping(port, 1) == (1020, COMM_SUCCESS, 0)
        # A READ answered and answered again at the next request to the same servo: the
        # SDK takes the stale status as the answer (it checks the ID, not the request).
        assert _position(link, 2) == 2048
        value, comm, error = ph.read2ByteTxRx(port, 2, 0)
        assert (value, comm, error) == (2048, COMM_SUCCESS, 0)  # not the model number 1020
        assert ph.read2ByteTxRx(port, 2, 0) == (1020, COMM_SUCCESS, 0)
        # A stale WRITE status (no data) answering read4ByteTxRx crashes the SDK's decoding.
        _ok(ph.write1ByteTxRx(port, 3, ADDR_TORQUE, 1))
        with pytest.raises(IndexError):
            ph.read4ByteTxRx(port, 3, ADDR_POSITION)
        port.is_using = False
        assert _position(link, 3) == 2048


def test_a_payload_that_needs_byte_stuffing() -> None:
    stuffed_position = -131073  # bytes FF FF FD FF
    events = (FaultEvent("stuffing", at_s=0.0, params={"id": 1,
                                                       "position": stuffed_position}),)
    for link in _faulty(*events, ids=(1,)):
        ph, port = link.ph, link.port
        assert _position(link, 1) == stuffed_position
        # The host's direction too: extended position mode, a goal that needs stuffing.
        _ok(ph.write1ByteTxRx(port, 1, ADDR_OPERATING_MODE, 4))
        _ok(ph.write1ByteTxRx(port, 1, ADDR_TORQUE, 1))
        for goal in (0, stuffed_position):
            _ok(ph.write4ByteTxRx(port, 1, ADDR_GOAL, goal))
            value, comm, error = ph.read4ByteTxRx(port, 1, ADDR_GOAL)
            assert (to_signed(value, 4), comm, error) == (goal, COMM_SUCCESS, 0)
        assert link.bus.stats["crc_errors"] == 0


def test_disconnect_via_the_harness(tmp_path: Path) -> None:
    """An unplugged adapter: the SDK raises on the next transaction (termios/serial errors,
    which a driver must catch); after the replug the stable path opens again and the
    power-cycled servos answer with torque off."""
    clock = MonotonicClock()
    faults = FaultSchedule(
        [FaultEvent("disconnect", at_s=clock.now() + 0.1, duration_s=0.1)],
        np.random.default_rng(0),
    )
    bus = DynamixelBus([1])
    link_path = tmp_path / "ttyDXL"
    with PtyEmulator(bus, clock=clock, faults=faults, link_path=link_path) as emulator:
        port = dynamixel_sdk.PortHandler(str(link_path))
        assert port.openPort()
        ph = dynamixel_sdk.PacketHandler(2.0)
        _ok(ph.write1ByteTxRx(port, 1, ADDR_TORQUE, 1))
        deadline = time.monotonic() + 1.0
        while emulator.connected and time.monotonic() < deadline:
            time.sleep(0.005)
        assert not emulator.connected
        with pytest.raises((termios.error, serial.SerialException, OSError)):
            ph.ping(port, 1)
        port.is_using = False
        while not emulator.connected and time.monotonic() < deadline:
            time.sleep(0.005)
        assert port.openPort()
        assert ph.ping(port, 1) == (1020, COMM_SUCCESS, 0)
        assert ph.read1ByteTxRx(port, 1, ADDR_TORQUE) == (0, COMM_SUCCESS, 0)
        port.closePort()
    assert emulator.stats["disconnects"] == 1 and bus.stats["power_cycles"] == 1


@pytest.mark.slow
def test_broadcast_ping_finds_every_servo(link: Link) -> None:
    """The SDK's broadcast ping waits out its whole window (about 0.8 s)."""
    found, comm = link.ph.broadcastPing(link.port)
    assert comm == COMM_SUCCESS
    assert {servo_id: info[0] for servo_id, info in found.items()} == {1: 1020, 2: 1020, 3: 1020}
