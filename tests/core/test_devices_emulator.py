"""Emulators of hapticframe.devices, opened by real pyserial through a pseudo-terminal."""

from __future__ import annotations

import os

import numpy as np
import pytest

from hapticframe.devices import (
    DeviceModel,
    EmulatedTransport,
    FakeClock,
    FaultEvent,
    FaultSchedule,
    FixedFrameParser,
    MonotonicClock,
    PtyEmulator,
    SerialTransport,
    TransportError,
    append_crc16,
)

serial = pytest.importorskip("serial")
pytestmark = pytest.mark.skipif(os.name != "posix", reason="pseudo-terminals are POSIX-only")

HEADER = b"\x20\x4e"


class Echo(DeviceModel):
    """Replies to each line with the line in capitals."""

    def __init__(self) -> None:
        self.pending = b""
        self.replies = bytearray()
        self.power_cycles = 0

    def receive(self, data: bytes, now_s: float) -> None:
        self.pending += data
        while b"\n" in self.pending:
            line, self.pending = self.pending.split(b"\n", 1)
            self.replies += line.upper() + b"\n"

    def emit(self, now_s: float) -> bytes:
        out = bytes(self.replies)
        self.replies.clear()
        return out

    def power_cycle(self) -> None:
        self.pending, self.power_cycles = b"", self.power_cycles + 1
        self.replies.clear()


class Stream(DeviceModel):
    """Sends a 16-byte frame every 10 ms carrying its sequence number."""

    def __init__(self) -> None:
        self.sent = 0
        self.start_s: float | None = None

    def receive(self, data: bytes, now_s: float) -> None:
        pass

    def emit(self, now_s: float) -> bytes:
        if self.start_s is None:
            self.start_s = now_s
        due = int((now_s - self.start_s) / 0.01 + 1e-9) + 1
        out = b"".join(frame(k) for k in range(self.sent, due))
        self.sent = max(self.sent, due)
        return out

    def power_cycle(self) -> None:
        self.start_s, self.sent = None, 0


def frame(k: int) -> bytes:
    return append_crc16(HEADER + np.array([k % 30_000, -k % 30_000, 0, 0, 1, 2], "<i2").tobytes())


def seq(frame_bytes: bytes) -> int:
    return int(np.frombuffer(frame_bytes[2:4], "<i2")[0])


def collect(transport, clock: FakeClock, parser: FixedFrameParser, steps: int) -> list[bytes]:
    frames: list[bytes] = []
    for _ in range(steps):
        clock.sleep(0.005)
        frames += parser.feed(transport.read_available())
    return frames


def test_plain_pyserial_talks_to_the_emulator(tmp_path):
    clock = FakeClock()
    with PtyEmulator(Echo(), clock=clock, link_path=tmp_path / "ttyECHO") as emulator:
        assert os.path.islink(emulator.path) and os.readlink(emulator.path).startswith("/dev/")
        port = serial.Serial(emulator.path, baudrate=19200, timeout=0)
        for word in (b"ping", b"\x11\x13\r raw bytes"):
            port.write(word + b"\n")
            clock.sleep(0.001)  # the emulator's listener services the pty here
            assert port.read(100) == word.upper() + b"\n"
        port.close()
        assert emulator.stats["bytes_in"] == emulator.stats["bytes_out"] == 5 + 14


def test_requests_split_across_writes_are_answered_once(tmp_path):
    clock = FakeClock()
    with PtyEmulator(Echo(), clock=clock) as emulator:
        link = SerialTransport(emulator.path, baudrate=115200)
        with link:
            for piece in (b"he", b"ll", b"o\nwor", b"ld\n"):
                link.write(piece)
                clock.sleep(0.001)
            assert link.read_available() == b"HELLO\nWORLD\n"
            assert link.read_available() == b""  # nothing more: at once, no waiting


def _waiting(fd: int) -> int:
    """Bytes readable on ``fd`` now (FIONREAD), without the overhead of a read call."""
    import fcntl
    import struct
    import termios

    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


def test_a_synchronous_pump_delivers_before_it_returns():
    # A pty moves bytes asynchronously: asked at once, the other side often has nothing yet
    # (over half the time on the machine where this was written). The emulator's delivery
    # barriers make every byte of a pump readable when the pump returns.
    clock = FakeClock()
    with PtyEmulator(Stream(), clock=clock) as emulator:
        link = SerialTransport(emulator.path, baudrate=19200)
        with link:
            fd = link.port.fileno()
            waiting = []
            for _ in range(300):
                clock.sleep(0.01)
                waiting.append(_waiting(fd))
                link.read_available()
    assert waiting == [16] * 300


def test_a_request_is_answered_by_the_next_pump():
    clock = FakeClock()
    with PtyEmulator(Echo(), clock=clock) as emulator:
        link = SerialTransport(emulator.path, baudrate=115200)
        with link:
            fd = link.port.fileno()
            for k in range(300):
                request = b"ping%03d\n" % k
                link.write(request)
                clock.sleep(0.001)
                assert _waiting(fd) == len(request), k
                assert link.read_available() == request.upper()


def test_fragmented_writes_arrive_intact():
    clock = FakeClock()
    faults = FaultSchedule([FaultEvent("fragment", at_s=0.0, duration_s=10.0)],
                           np.random.default_rng(3))
    with PtyEmulator(Stream(), clock=clock, faults=faults) as emulator:
        link = SerialTransport(emulator.path, baudrate=19200)
        link.open()
        parser = FixedFrameParser(HEADER, 16)
        sizes = []
        frames: list[bytes] = []
        for _ in range(200):
            clock.sleep(0.005)
            data = link.read_available()
            sizes.append(len(data))
            frames += parser.feed(data)
        link.close()
    assert [seq(f) for f in frames] == list(range(len(frames)))
    assert len(frames) >= 80 and parser.stats.crc_errors == 0
    assert any(0 < size < 16 for size in sizes)  # really split into pieces
    assert faults.count("fragment") == 1


def test_dropped_and_garbage_bytes_cost_frames_not_sync():
    clock = FakeClock()
    faults = FaultSchedule(
        [FaultEvent("drop_bytes", at_s=0.1, params={"count": 3}),
         FaultEvent("garbage", at_s=0.3, params={"count": 5})],
        np.random.default_rng(5),
    )
    with PtyEmulator(Stream(), clock=clock, faults=faults) as emulator:
        link = SerialTransport(emulator.path, baudrate=19200)
        link.open()
        parser = FixedFrameParser(HEADER, 16)
        frames = collect(link, clock, parser, 120)
        link.close()
    numbers = [seq(f) for f in frames]
    assert numbers == sorted(numbers) and numbers[-1] >= 58
    lost = numbers[-1] + 1 - len(numbers)
    assert 1 <= lost <= 3  # the frame with missing bytes, and at most two around the noise
    assert parser.stats.resyncs > 0
    assert emulator.stats["dropped"] == 3 and faults.count("garbage") == 1


@pytest.mark.parametrize("drop", [0, 1])
def test_a_stall_delays_or_drops_the_bytes(drop):
    clock = FakeClock()
    faults = FaultSchedule([FaultEvent("stall", at_s=0.1, duration_s=0.1, params={"drop": drop})],
                           np.random.default_rng(0))
    with PtyEmulator(Stream(), clock=clock, faults=faults) as emulator:
        link = SerialTransport(emulator.path, baudrate=19200)
        link.open()
        parser = FixedFrameParser(HEADER, 16)
        during = collect(link, clock, parser, 20)  # to t = 0.1
        quiet = collect(link, clock, parser, 19)  # t in (0.1, 0.195]: nothing arrives
        after = collect(link, clock, parser, 10)
        link.close()
    assert quiet == [] and during
    numbers = [seq(f) for f in during + after]
    if drop:
        assert emulator.stats["dropped"] > 100 and numbers[-1] + 1 - len(numbers) >= 8
    else:  # the late bytes all come in one burst
        assert numbers == list(range(len(numbers)))


def test_disconnect_raises_and_a_reopen_after_replug_works(tmp_path):
    clock = FakeClock()
    model = Echo()
    link_path = tmp_path / "by-id" / "usb-lab-device"
    link_path.parent.mkdir()
    with PtyEmulator(model, clock=clock, link_path=link_path) as emulator:
        link = SerialTransport(str(link_path), baudrate=19200)
        link.open()
        emulator.disconnect()
        with pytest.raises(TransportError):
            link.read_available()
        link.close()
        with pytest.raises(TransportError, match="cannot open"):
            link.open()  # unplugged: the by-id link is gone
        emulator.replug()
        assert model.power_cycles == 1 and os.readlink(link_path).startswith("/dev/")
        link.open()  # the same path, now the new pty
        link.write(b"back\n")
        clock.sleep(0.001)
        assert link.read_available() == b"BACK\n"
        link.close()
        assert emulator.stats["disconnects"] == 1


def test_a_disconnect_fault_replugs_after_its_duration(tmp_path):
    clock = FakeClock()
    faults = FaultSchedule([FaultEvent("disconnect", at_s=0.05, duration_s=0.1)],
                           np.random.default_rng(0))
    model = Stream()
    with PtyEmulator(model, clock=clock, faults=faults, link_path=tmp_path / "dev") as emulator:
        link = SerialTransport(emulator.path, baudrate=19200)
        link.open()
        parser = FixedFrameParser(HEADER, 16)
        with pytest.raises(TransportError):
            collect(link, clock, parser, 40)
        link.close()
        disconnected_at = clock.now()
        while not emulator.connected:
            clock.sleep(0.01)
        assert 0.15 <= clock.now() <= disconnected_at + 0.11
        link.open()
        frames = collect(link, clock, parser, 20)
        link.close()
    assert len(frames) >= 8 and faults.count("disconnect") == 1


def test_a_full_pty_drops_and_counts_instead_of_blocking():
    clock = FakeClock()
    with PtyEmulator(Stream(), clock=clock) as emulator:
        port = serial.Serial(emulator.path, timeout=0)  # opened and never read
        clock.advance(0.0)
        clock.advance(200.0)  # 20 000 frames due at once: far more than a pty holds
        assert emulator.stats["overruns"] >= 1
        assert emulator.stats["bytes_out"] < 16 * 20_000
        port.close()


def test_a_monotonic_clock_runs_a_service_thread():
    clock = MonotonicClock()
    with PtyEmulator(Echo(), clock=clock) as emulator:
        link = SerialTransport(emulator.path, baudrate=115200)
        with link:
            link.write(b"threaded\n")
            reply = b""
            for _ in range(5000):  # generous: up to ~5 s on a loaded machine
                reply += link.read_available()
                if reply.endswith(b"\n"):
                    break
                clock.sleep(0.001)
            assert reply == b"THREADED\n"


def test_thread_true_serves_a_fake_clock_in_a_thread():
    """thread=True: a host that blocks waiting for a reply (as dynamixel_sdk does) is
    answered although nobody advances the FakeClock; the model sees the clock's time."""
    clock = FakeClock(5.0)
    model = Echo()
    seen: list[float] = []
    receive = model.receive
    model.receive = lambda data, now_s: (seen.append(now_s), receive(data, now_s))
    with PtyEmulator(model, clock=clock, thread=True) as emulator:
        assert not clock._listeners  # no listener: the thread pumps
        port = serial.Serial(emulator.path, timeout=5.0)
        try:
            port.write(b"blocked\n")
            assert port.readline() == b"BLOCKED\n"
        finally:
            port.close()
    assert seen and set(seen) == {5.0}
    with pytest.raises(ValueError, match="FakeClock"):
        PtyEmulator(Echo(), clock=MonotonicClock(), thread=False)


def test_emulated_transport_streams_and_survives_a_disconnect():
    clock = FakeClock()
    faults = FaultSchedule(
        [FaultEvent("fragment", at_s=0.0, duration_s=0.2),
         FaultEvent("disconnect", at_s=0.3, duration_s=0.05)],
        np.random.default_rng(1),
    )
    model = Stream()
    link = EmulatedTransport(model, clock, faults)
    link.open()
    parser = FixedFrameParser(HEADER, 16)
    with pytest.raises(TransportError, match="disconnected"):
        collect(link, clock, parser, 100)
    assert clock.now() == pytest.approx(0.3)
    link.close()
    with pytest.raises(TransportError, match="unplugged"):
        link.open()
    clock.advance(0.05)
    link.open()
    parser.reset()
    frames = collect(link, clock, parser, 20)
    assert [seq(f) for f in frames][:3] == [0, 1, 2]  # power-cycled: counting again
    assert link.stats["disconnects"] == 1 and parser.stats.crc_errors == 0


def test_emulated_transport_echo_and_reset_input():
    clock = FakeClock()
    link = EmulatedTransport(Echo(), clock)
    with pytest.raises(TransportError):
        link.write(b"x\n")  # not open yet
    with link:
        link.write(b"a\nb\n")
        link.reset_input()
        assert link.read_available() == b""  # the replies were flushed unread
        link.write(b"c\n")
        assert link.read_available(1) == b"C" and link.read_available() == b"\n"
    assert not link.is_open
