"""Dynamixel Protocol 2.0 packets, the XM430-W350 table, and the bus model in-process."""

from __future__ import annotations

import math

import numpy as np
import pytest
from dynamixel_sdk import protocol2_packet_handler as sdk_p2  # type: ignore[import-untyped]

from hapticframe.devices import FaultEvent, FaultSchedule
from hapticframe_dynamixel import (
    ERR_ACCESS,
    ERR_ALERT,
    ERR_DATA_RANGE,
    FAULT_KINDS,
    HW_ERROR_OVERLOAD,
    INST_PING,
    XM430_W350,
    DynamixelBus,
    PacketParser,
    ProtocolError,
    StatusPacket,
    amps_to_current,
    crc16_dxl,
    current_to_amps,
    decode_instruction,
    decode_status,
    encode_status,
    error_name,
    ping_packet,
    pulses_to_rad,
    rad_to_pulses,
    read_packet,
    reboot_packet,
    stuff,
    sync_read_packet,
    sync_write_packet,
    to_signed,
    unstuff,
    write_packet,
)

# --- known answers --------------------------------------------------------------------------


def test_crc_known_answers() -> None:
    assert crc16_dxl(b"123456789") == 0xFEE8
    assert ping_packet(1) == bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E")
    handler = sdk_p2.Protocol2PacketHandler()
    data = bytes(np.random.default_rng(1).integers(0, 256, 200, dtype=np.uint8))
    assert crc16_dxl(data) == handler.updateCRC(0, list(data), len(data))


def test_instruction_packets_decode_back() -> None:
    packet = decode_instruction(read_packet(7, 132, 4))
    assert (packet.id, packet.instruction, packet.params) == (7, 0x02, bytes([132, 0, 4, 0]))
    packet = decode_instruction(write_packet(2, 116, (-5).to_bytes(4, "little", signed=True)))
    assert packet.params[2:] == b"\xfb\xff\xff\xff"
    packet = decode_instruction(sync_read_packet(126, 10, [1, 2, 3]))
    assert (packet.id, packet.instruction, packet.params) == (
        0xFE, 0x82, bytes([126, 0, 10, 0, 1, 2, 3]),
    )
    packet = decode_instruction(sync_write_packet(116, 4, {1: b"\0\1\0\0", 2: b"\0\2\0\0"}))
    assert packet.params == bytes([116, 0, 4, 0, 1, 0, 1, 0, 0, 2, 0, 2, 0, 0])
    assert decode_instruction(reboot_packet(3)).instruction == 0x08
    with pytest.raises(ProtocolError):
        sync_write_packet(116, 4, {1: b"\0"})


def test_status_packet_and_error_byte() -> None:
    frame = encode_status(1, 0, bytes([0xFC, 0x03, 48]))
    status = decode_status(frame)
    assert status == StatusPacket(1, 0, bytes([0xFC, 0x03, 48]))
    assert int.from_bytes(status.params[:2], "little") == 1020
    alert = decode_status(encode_status(2, ERR_ALERT | ERR_ACCESS))
    assert alert.alert and alert.error_number == ERR_ACCESS
    assert alert.error_name == "access error, alert"
    assert [error_name(n) for n in range(1, 8)] == [
        "result fail", "instruction error", "CRC error", "data range error",
        "data length error", "data limit error", "access error",
    ]
    with pytest.raises(ProtocolError, match="CRC"):
        decode_status(frame[:-1] + bytes([frame[-1] ^ 1]))
    with pytest.raises(ProtocolError):
        decode_status(ping_packet(1))  # an instruction, not a status


# --- byte stuffing --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "body",
    [
        b"",
        b"\xff\xff\xfd",
        b"\xff\xff\xfd\xfd",
        b"\x55\x00\xff\xff\xfd\xff",
        b"\xff\xff\xfd\xff\xff\xfd\x00",
        b"\xff\xff\xff\xfd",
    ],
)
def test_stuffing_round_trips(body: bytes) -> None:
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    assert stuffed.count(b"\xff\xff\xfd\xfd") >= body.count(b"\xff\xff\xfd")
    # No header left inside: every FF FF FD in the stuffed body is followed by FD.
    index = stuffed.find(b"\xff\xff\xfd")
    while index >= 0:
        assert stuffed[index + 3 : index + 4] == b"\xfd"
        index = stuffed.find(b"\xff\xff\xfd", index + 1)


def test_stuffing_random_payloads_and_the_sdk_agree() -> None:
    rng = np.random.default_rng(3)
    handler = sdk_p2.Protocol2PacketHandler()
    for _ in range(200):
        params = bytes(rng.choice([0xFF, 0xFD, 0x00, 0x12], size=int(rng.integers(0, 30))))
        ours = encode_status(5, 0, params)
        assert decode_status(ours).params == params
        # The SDK's own stuffing and CRC of the same unstuffed packet.
        raw = list(b"\xff\xff\xfd\x00\x05") + [0, 0, 0x55, 0] + list(params) + [0, 0]
        length = len(params) + 4
        raw[5], raw[6] = length & 0xFF, length >> 8
        sdk = handler.addStuffing(raw)
        total = (sdk[5] | sdk[6] << 8) + 7
        crc = handler.updateCRC(0, sdk, total - 2)
        sdk[total - 2], sdk[total - 1] = crc & 0xFF, crc >> 8
        assert bytes(sdk[:total]) == ours


def test_a_write_whose_payload_holds_a_header_is_stuffed() -> None:
    value = (-131073).to_bytes(4, "little", signed=True)
    assert value == b"\xff\xff\xfd\xff"
    frame = write_packet(1, 116, value)
    assert b"\xff\xff\xfd\xfd\xff" in frame
    assert decode_instruction(frame).params[2:] == value


# --- the parser -----------------------------------------------------------------------------


def _stream() -> tuple[bytes, list[StatusPacket]]:
    packets = [
        StatusPacket(1, 0, bytes([0xFC, 0x03, 48])),
        StatusPacket(2, 0x80, b""),
        StatusPacket(3, 0, b"\xff\xff\xfd\xff\x00\x01"),
        StatusPacket(4, ERR_DATA_RANGE, b""),
    ]
    return b"".join(encode_status(p.id, p.error, p.params) for p in packets), packets


def test_parser_any_split() -> None:
    stream, expected = _stream()
    rng = np.random.default_rng(0)
    for _ in range(50):
        parser = PacketParser()
        cuts = sorted(rng.integers(0, len(stream), size=5))
        got = []
        for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True):
            got += parser.feed(stream[a:b])
        assert got == expected
        assert parser.counters.crc_errors == 0 and parser.counters.resyncs == 0


def test_parser_resyncs_after_junk_bad_header_and_half_packet() -> None:
    stream, expected = _stream()
    first = encode_status(1, 0, bytes([0xFC, 0x03, 48]))
    bad_reserved = b"\xff\xff\xfd\x01\x01\x03\x00\x55"  # reserved != 0: drop one byte
    half = first[:9]  # header, ID, LEN, INST, ERR: a plausible start
    parser = PacketParser()
    got = parser.feed(b"\x00\x13\xfd" + bad_reserved + half + stream)
    assert got == expected
    assert parser.counters.bad_headers >= 1
    # The half packet's LEN made it swallow the next bytes: a CRC error, then one-byte resync.
    assert parser.counters.crc_errors == 1
    assert parser.counters.resyncs >= 3 + len(bad_reserved) + len(half)


def test_parser_drops_corrupt_crc_and_keeps_the_next() -> None:
    stream, expected = _stream()
    corrupt = encode_status(9, 0, b"\x01\x02")
    corrupt = corrupt[:-1] + bytes([corrupt[-1] ^ 0xFF])
    parser = PacketParser()
    assert parser.feed(corrupt + stream) == expected
    assert parser.counters.crc_errors == 1


def test_instruction_parser_rejects_status() -> None:
    parser = PacketParser(status=False)
    got = parser.feed(encode_status(1) + ping_packet(2) + sync_read_packet(132, 4, [1, 2]))
    assert [p.instruction for p in got] == [INST_PING, 0x82]  # type: ignore[union-attr]


# --- control table --------------------------------------------------------------------------


def test_control_table_matches_the_notes() -> None:
    table = XM430_W350
    assert table.model_number == 1020
    expected = {
        "Model Number": (0, 2), "ID": (7, 1), "Baud Rate": (8, 1), "Return Delay Time": (9, 1),
        "Operating Mode": (11, 1), "Current Limit": (38, 2), "Max Position Limit": (48, 4),
        "Min Position Limit": (52, 4), "Shutdown": (63, 1), "Torque Enable": (64, 1),
        "Status Return Level": (68, 1), "Hardware Error Status": (70, 1),
        "Bus Watchdog": (98, 1), "Goal Current": (102, 2), "Goal Velocity": (104, 4),
        "Profile Acceleration": (108, 4), "Profile Velocity": (112, 4),
        "Goal Position": (116, 4), "Moving": (122, 1), "Moving Status": (123, 1),
        "Present Current": (126, 2), "Present Velocity": (128, 4),
        "Present Position": (132, 4), "Present Input Voltage": (144, 2),
        "Present Temperature": (146, 1),
    }
    for name, (address, size) in expected.items():
        assert (table[name].address, table[name].size) == (address, size), name
    assert table["ID"].area == "EEPROM" and table["Torque Enable"].area == "RAM"
    assert not table["Present Position"].writable
    assert table.at(134) is table["Present Position"] and table.at(14) is None
    memory = table.defaults()
    assert int.from_bytes(memory[0:2], "little") == 1020


def test_unit_conversions() -> None:
    assert pulses_to_rad(4096) == pytest.approx(2 * math.pi)
    assert rad_to_pulses(math.pi / 2) == 1024
    assert current_to_amps(65499) == pytest.approx(-37 * 2.69e-3)  # SDK's unsigned reading
    assert current_to_amps(100) == pytest.approx(0.269)
    assert amps_to_current(-0.0995) == -37
    assert to_signed(0xFFFDFFFF, 4) == -131073


# --- the bus model in-process ---------------------------------------------------------------


def _ask(bus: DynamixelBus, packet: bytes, t: float) -> list[StatusPacket]:
    bus.receive(packet, t)
    parser = PacketParser()
    return parser.feed(bus.emit(t + 0.01))  # type: ignore[return-value]


def test_bus_model_answers_in_process() -> None:
    bus = DynamixelBus([1, 2])
    [status] = _ask(bus, ping_packet(2), 0.0)
    assert status.id == 2 and int.from_bytes(status.params[:2], "little") == 1020
    assert _ask(bus, ping_packet(9), 0.0) == []
    replies = _ask(bus, sync_read_packet(0, 2, [2, 1]), 0.1)
    assert [r.id for r in replies] == [2, 1]
    [status] = _ask(bus, write_packet(1, 64, b"\x01"), 0.2)
    assert status.error == 0
    [status] = _ask(bus, write_packet(1, 11, b"\x04"), 0.3)  # EEPROM with torque on
    assert status.error == ERR_ACCESS
    [status] = _ask(bus, write_packet(1, 116, (5000).to_bytes(4, "little")), 0.4)
    assert status.error == ERR_DATA_RANGE
    [status] = _ask(bus, write_packet(1, 132, b"\0\0\0\0"), 0.5)  # read-only
    assert status.error == ERR_ACCESS
    _ask(bus, write_packet(1, 68, b"\x00"), 0.6)  # Status Return Level 0: only pings answer
    assert _ask(bus, read_packet(1, 132, 4), 0.7) == []
    assert len(_ask(bus, ping_packet(1), 0.8)) == 1


def test_bus_model_dynamics_are_first_order() -> None:
    bus = DynamixelBus([1], time_constant_s=0.05)
    _ask(bus, write_packet(1, 64, b"\x01"), 0.0)
    _ask(bus, write_packet(1, 116, (3048).to_bytes(4, "little")), 0.02)
    [status] = _ask(bus, read_packet(1, 132, 4), 0.06)  # 40 ms after the goal
    position = int.from_bytes(status.params, "little", signed=True)
    assert position == pytest.approx(3048 - 1000 * math.exp(-0.04 / 0.05), abs=2)
    [status] = _ask(bus, read_packet(1, 128, 4), 0.07)
    assert int.from_bytes(status.params, "little", signed=True) > 0  # moving up


def test_bus_model_overload_latches_until_reboot() -> None:
    bus = DynamixelBus([1], loads={1: lambda t: 0.0 if t < 1.0 else 8.0}, load_unit="nm")
    _ask(bus, write_packet(1, 64, b"\x01"), 0.0)
    [status] = _ask(bus, read_packet(1, 126, 2), 0.5)
    assert status.error == 0 and bus.servo(1).torque_enabled
    for t in np.arange(1.0, 1.1, 0.01):
        bus.emit(float(t))
    servo = bus.servo(1)
    assert servo.hardware_error & HW_ERROR_OVERLOAD and not servo.torque_enabled
    [status] = _ask(bus, write_packet(1, 64, b"\x01"), 1.2)
    assert status.alert and not servo.torque_enabled
    [status] = _ask(bus, reboot_packet(1), 1.3)
    assert status.alert  # the answer comes before the reboot
    [status] = _ask(bus, ping_packet(1), 1.4)
    assert not status.alert and servo.hardware_error == 0


def test_fault_kinds_are_documented_and_fire() -> None:
    assert {"no_reply", "bad_crc", "error_code", "late_reply", "late_duplicate", "junk",
            "stuffing", "sync_missing", "hardware_error", "current_spike"} <= set(FAULT_KINDS)
    faults = FaultSchedule(
        [FaultEvent("bad_crc", at_s=0.0), FaultEvent("junk", at_s=0.0, params={"count": 4}),
         FaultEvent("no_reply", at_s=0.5, params={"id": 2})],
        np.random.default_rng(0),
    )
    bus = DynamixelBus([1, 2], faults=faults)
    bus.receive(ping_packet(1), 0.1)
    out = bus.emit(0.2)
    parser = PacketParser()
    assert parser.feed(out) == []
    assert parser.counters.crc_errors == 1 and len(out) == 4 + 14
    assert len(_ask(bus, ping_packet(1), 0.6)) == 1  # the no_reply waits for servo 2
    assert _ask(bus, ping_packet(2), 0.7) == []
    assert [s.fault for s in bus.sent] == ["bad_crc", "", "no_reply"]


def test_hardware_error_and_current_spike_faults() -> None:
    faults = FaultSchedule(
        [FaultEvent("hardware_error", at_s=0.5, params={"id": 2, "bit": 2}),
         FaultEvent("current_spike", at_s=1.0, duration_s=0.1, params={"amps": 4.0})],
        np.random.default_rng(0),
    )
    bus = DynamixelBus([1, 2], faults=faults)
    for servo_id in (1, 2):
        _ask(bus, write_packet(servo_id, 64, b"\x01"), 0.0)
    [status] = _ask(bus, ping_packet(2), 0.6)
    assert status.alert and bus.servo(2).hardware_error == 1 << 2
    assert not bus.servo(2).torque_enabled  # Shutdown (52) has the overheating bit
    assert bus.servo(1).hardware_error == 0
    for t in np.arange(0.9, 1.2, 0.005):
        bus.emit(float(t))
    assert bus.servo(1).hardware_error == HW_ERROR_OVERLOAD
    assert bus.stats["overloads"] == 1


def test_broadcast_ping_and_power_cycle() -> None:
    bus = DynamixelBus([3, 1, 2])
    replies = _ask(bus, ping_packet(0xFE), 0.0)
    assert [r.id for r in replies] == [1, 2, 3]
    _ask(bus, write_packet(1, 7, b"\x09"), 0.1)  # a new ID (EEPROM, torque off)
    _ask(bus, write_packet(9, 64, b"\x01"), 0.2)
    bus.power_cycle()
    assert bus.servo(9).get("ID") == 9 and not bus.servo(9).torque_enabled
