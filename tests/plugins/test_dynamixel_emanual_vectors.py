"""The ROBOTIS e-manual's Protocol 2.0 example packets, byte for byte (issue 28 §4).

Source: the DYNAMIXEL Protocol 2.0 page of the ROBOTIS e-manual, repository
``ROBOTIS-GIT/emanual``, file ``docs/en/dxl/protocol2.md`` (commit 01179568a085), sections
"Instruction Details": Ping (examples 1 and 2), Read, Write, Reg Write, Action, Factory
Reset, Reboot, Clear, Sync Read, Sync Write and Bulk Read. Only the byte vectors are copied
here; each is an instruction packet and the status packet(s) the manual prints for it.
The encoder must produce the instruction packets, the decoder must accept the status
packets (their CRCs included), and the emulated bus must answer the manual's instruction
packets with the manual's status packets when its servos hold the manual's values.
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe_dynamixel import (
    XM430_W350,
    DynamixelBus,
    bulk_read_packet,
    crc16_dxl,
    decode_instruction,
    decode_status,
    encode_instruction,
    encode_status,
    ping_packet,
    read_packet,
    reboot_packet,
    sync_read_packet,
    sync_write_packet,
    write_packet,
)


def _b(text: str) -> bytes:
    return bytes(int(x, 16) for x in text.split())


# (name, instruction packet, status packets) as printed in the e-manual.
PING_1 = _b("FF FF FD 00 01 03 00 01 19 4E")
PING_BROADCAST = _b("FF FF FD 00 FE 03 00 01 31 42")
PING_STATUS_1 = _b("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D")
PING_STATUS_2 = _b("FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D")
READ = _b("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")
READ_STATUS = _b("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0")
WRITE = _b("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")
EMPTY_STATUS_1 = _b("FF FF FD 00 01 04 00 55 00 A1 0C")
REG_WRITE = _b("FF FF FD 00 01 09 00 04 68 00 C8 00 00 00 AE 8E")
ACTION = _b("FF FF FD 00 01 03 00 05 02 CE")
FACTORY_RESET = _b("FF FF FD 00 01 04 00 06 01 A1 E6")
REBOOT = _b("FF FF FD 00 01 03 00 08 2F 4E")
CLEAR = _b("FF FF FD 00 01 08 00 10 01 44 58 4C 22 B1 DC")
SYNC_READ = _b("FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA")
SYNC_READ_STATUS_2 = _b("FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE")
SYNC_WRITE = _b("FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87")
BULK_READ = _b("FF FF FD 00 FE 0D 00 92 01 90 00 02 00 02 92 00 01 00 1A 05")
BULK_READ_STATUS_1 = _b("FF FF FD 00 01 06 00 55 00 77 00 C3 69")
BULK_READ_STATUS_2 = _b("FF FF FD 00 02 05 00 55 00 24 8B A9")

ALL = [PING_1, PING_BROADCAST, PING_STATUS_1, PING_STATUS_2, READ, READ_STATUS, WRITE,
       EMPTY_STATUS_1, REG_WRITE, ACTION, FACTORY_RESET, REBOOT, CLEAR, SYNC_READ,
       SYNC_READ_STATUS_2, SYNC_WRITE, BULK_READ, BULK_READ_STATUS_1, BULK_READ_STATUS_2]


@pytest.mark.parametrize("packet", ALL, ids=range(len(ALL)))
def test_every_printed_crc_is_the_crc_of_its_packet(packet):
    assert crc16_dxl(packet[:-2]) == int.from_bytes(packet[-2:], "little")


def test_the_encoder_produces_the_manual_instruction_packets():
    assert ping_packet(1) == PING_1
    assert ping_packet(0xFE) == PING_BROADCAST
    assert read_packet(1, 132, 4) == READ
    assert write_packet(1, 116, (512).to_bytes(4, "little")) == WRITE
    assert reboot_packet(1) == REBOOT
    assert sync_read_packet(132, 4, [1, 2]) == SYNC_READ
    assert sync_write_packet(116, 4, {1: (150).to_bytes(4, "little"),
                                      2: (170).to_bytes(4, "little")}) == SYNC_WRITE
    assert bulk_read_packet([(1, 144, 2), (2, 146, 1)]) == BULK_READ
    # Instructions the driver does not send, through the generic encoder.
    assert encode_instruction(1, 0x04, _b("68 00 C8 00 00 00")) == REG_WRITE
    assert encode_instruction(1, 0x05) == ACTION
    assert encode_instruction(1, 0x06, b"\x01") == FACTORY_RESET
    assert encode_instruction(1, 0x10, _b("01 44 58 4C 22")) == CLEAR


def test_the_decoder_reads_the_manual_status_packets():
    ping = decode_status(PING_STATUS_1)
    assert (ping.id, ping.error, ping.params) == (1, 0, _b("06 04 26"))
    assert int.from_bytes(ping.params[:2], "little") == 1030  # XM430-W210's model number
    read = decode_status(READ_STATUS)
    assert int.from_bytes(read.params, "little") == 166
    second = decode_status(SYNC_READ_STATUS_2)
    assert (second.id, int.from_bytes(second.params, "little")) == (2, 2079)
    assert decode_status(BULK_READ_STATUS_1).params == _b("77 00")  # 119: 11.9 V
    assert decode_status(BULK_READ_STATUS_2).params == b"\x24"  # 36 °C
    assert decode_status(EMPTY_STATUS_1).params == b""
    assert encode_status(2, 0, b"\x24") == BULK_READ_STATUS_2
    instruction = decode_instruction(BULK_READ)
    assert (instruction.id, instruction.instruction) == (0xFE, 0x92)
    with pytest.raises(Exception, match="CRC"):
        decode_status(READ_STATUS[:-1] + b"\x00")


def _answers(bus: DynamixelBus, packet: bytes) -> bytes:
    bus.receive(packet, 1.0)
    return bus.emit(2.0)


def _bus_with_manual_values() -> DynamixelBus:
    bus = DynamixelBus([1, 2], rng=np.random.default_rng(0))
    for servo in bus.servos:
        servo.set("Return Delay Time", 0)
    return bus


def test_the_emulated_bus_answers_the_manual_sync_and_bulk_reads_byte_for_byte():
    bus = _bus_with_manual_values()
    bus.servo(1).set("Present Position", 166)
    bus.servo(2).set("Present Position", 2079)
    bus.servo(1).set("Present Input Voltage", 119)
    bus.servo(2).set("Present Temperature", 36)
    # The emulated servos move in model time: freeze them where the manual has them.
    for servo in bus.servos:
        servo.position = float(servo.get("Present Position"))
        servo.set("Goal Position", servo.get("Present Position"))
    assert _answers(bus, READ) == READ_STATUS
    assert _answers(bus, SYNC_READ) == READ_STATUS + SYNC_READ_STATUS_2
    assert _answers(bus, BULK_READ) == BULK_READ_STATUS_1 + BULK_READ_STATUS_2
    assert XM430_W350["Present Input Voltage"].address == 144
    assert XM430_W350["Present Temperature"].address == 146


def test_a_bulk_read_that_lists_a_servo_twice_is_refused():
    with pytest.raises(Exception, match="twice"):
        bulk_read_packet([(1, 144, 2), (1, 146, 1)])
    bus = _bus_with_manual_values()
    twice = encode_instruction(0xFE, 0x92, _b("01 90 00 02 00 01 92 00 01 00"))
    assert _answers(bus, twice) == b""
    assert bus.stats["ignored"] == 1
