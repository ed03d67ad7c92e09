"""A rehearsal of the hardware tests: the same tests, on the live path, against emulators.

The device plugins' own tests pace their emulators with a FakeClock. Here each emulator
runs in its own thread behind a real pseudo-terminal on the wall clock, as a USB adapter
would, and the sensors open its path as a real port (``live``, MonotonicClock): the path a
lab's rig takes, minus the hardware.
"""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe.devices import MonotonicClock, PtyEmulator

from . import test_real_devices as real


@pytest.fixture
def ft300_port(tmp_path, monkeypatch):
    from hapticframe_robotiq import Ft300Model, Ft300Physics

    # A real sensor's noise: without it every frame at rest is the same, which the driver
    # rightly takes for a frozen sensor.
    physics = Ft300Physics(noise_std_n=0.03, noise_std_nm=0.0005, offset_n=(0.4, -0.2, 1.1))
    model = Ft300Model(rng=np.random.default_rng(5), physics=physics)
    with PtyEmulator(model, clock=MonotonicClock(), link_path=tmp_path / "ttyFT300") as pty:
        monkeypatch.setenv("HAPTICFRAME_FT300_PORT", pty.path)
        yield pty


@pytest.fixture
def bno055_port(tmp_path, monkeypatch):
    from hapticframe_bno055 import Bno055Model

    model = Bno055Model(rng=np.random.default_rng(6), accel_noise_std_m_per_s2=0.02)
    with PtyEmulator(model, clock=MonotonicClock(), link_path=tmp_path / "ttyIMU") as pty:
        monkeypatch.setenv("HAPTICFRAME_BNO055_PORT", pty.path)
        yield pty


def test_ft300_rehearsal(ft300_port):
    real.test_ft300_streams_tared_forces_at_100_hz()
    assert ft300_port.stats["bytes_out"] > 100 * 16


def test_bno055_rehearsal(bno055_port):
    real.test_bno055_reads_gravity_at_rest()
    assert bno055_port.stats["bytes_in"] > 0  # the driver polled the emulator
