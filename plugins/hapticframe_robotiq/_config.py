"""Config model of the Robotiq FT 300 sensor (import-light: pydantic and hapticframe only)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, model_validator

from hapticframe import PluginConfig
from hapticframe.devices import FaultKind, FaultKinds, FaultParam, FaultValue

__all__ = ["FAULT_KINDS", "EMULATED_PORT", "Ft300Config"]

#: The emulator's own fault kinds (hapticframe_robotiq._emulator.FAULT_KINDS describes them);
#: the harness adds the byte-level ones. ``validate`` refuses any other kind and parameter.
FAULT_KINDS: dict[str, FaultKind] = {
    "boots_streaming": FaultKind("already streaming when the host connects"),
    "partial_jam": FaultKind("a jam (run of 0xFF) that does not stop the stream"),
    "bad_crc": FaultKind("one stream frame with a corrupted CRC"),
    "frame_drop_bytes": FaultKind("params.count bytes lost inside one stream frame",
                                  {"count": FaultParam(1, 13, integer=True)}),
    "header_in_payload": FaultKind("a frame whose payload holds 0x20 0x4E at params.offset",
                                   {"offset": FaultParam(0, 10, integer=True)}),
    "stream_stop": FaultKind("the stream stops silently for duration_s"),
    "saturation": FaultKind("every value pinned at the range limit for duration_s"),
    "offset_drift": FaultKind("the force offset drifts at params.rate_n_per_s",
                              {"rate_n_per_s": FaultParam(-1000.0, 1000.0)}),
    "frozen": FaultKind("the same frame repeated, CRC valid, for duration_s"),
    "no_reply": FaultKind("one Modbus request left unanswered"),
    "modbus_bad_crc": FaultKind("one Modbus reply with a corrupted CRC"),
    "wrong_slave": FaultKind("one Modbus reply from another slave id"),
    "exception_reply": FaultKind("one Modbus request answered with exception 4"),
    "missing_echo": FaultKind("the function 16 echo is missing while the stream starts"),
    "dead": FaultKind("the sensor falls silent to everything for duration_s"),
}
#: The ``port`` that runs the sensor's emulator behind a pseudo-terminal.
EMULATED_PORT = "emulated"

Vector3 = tuple[float, float, float]


class Ft300Config(PluginConfig):
    """A Robotiq FT 300 wrist force/torque sensor on a USB-serial adapter, or its emulator.

    The driver identifies the sensor over Modbus RTU, starts its 100 Hz stream, zeroes it
    over ``tare_s`` and watches the stream in time: no byte for ``byte_timeout_s`` counts a
    stall, no valid frame for ``frame_timeout_s`` restarts the stream (reconnecting first
    when the link dropped). With ``port: emulated`` the same driver talks to the sensor's
    emulator through a pseudo-terminal; the emulator computes each frame from the physical
    truth of the robot named in ``inputs`` (at rest without one) and injects ``faults``.
    """

    port: str = Field(
        ...,
        min_length=1,
        description="A device path (/dev/ttyUSB0, /dev/serial/by-id/...), a pyserial URL, or "
        "'emulated' for the sensor's emulator behind a pseudo-terminal.",
    )
    baudrate: int = Field(
        19200, gt=0, le=10_000_000,
        description="Serial speed (the FT 300 uses 19200 8N1).",
    )
    slave_id: int = Field(9, ge=1, le=247, description="Modbus slave id (the FT 300 uses 9).")
    tare_s: float = Field(
        0.2,
        ge=0,
        le=10,
        description="Zeroing window at activation (and on request): the mean of the valid "
        "samples over this long is subtracted from every later sample; 0 delivers raw values.",
    )
    byte_timeout_s: float = Field(
        0.08, gt=0, le=10.0, description="No byte for this long counts a stall (and ends a jam)."
    )
    frame_timeout_s: float = Field(
        0.16,
        gt=0,
        le=60.0,
        description="No valid frame for this long: recover (re-jam and restart the stream, "
        "reconnecting first when the link dropped).",
    )
    modbus_timeout_s: float = Field(
        0.4, gt=0, le=60.0, description="How long one Modbus request waits for its reply."
    )
    modbus_retries: int = Field(
        3, ge=1, le=20, description="Attempts of one Modbus request before it fails."
    )
    jam_attempts: int = Field(
        5, ge=1, le=50, description="0xFF bursts sent at most to silence a running stream."
    )
    reconnect_attempts: int = Field(
        5, ge=1, le=50, description="Reopen attempts (with exponential backoff) after a link drop."
    )
    max_recoveries: int = Field(
        3,
        ge=1,
        le=100,
        description="Failed recoveries in a row after which the device gives up (DeviceError).",
    )
    range_n: float = Field(
        300.0,
        gt=0,
        le=327.67,
        description="Force range: a sample with a force component at or beyond it is saturated "
        "and marked invalid.",
    )
    range_nm: float = Field(
        30.0,
        gt=0,
        le=32.767,
        description="Torque range: a sample with a torque component at or beyond it is "
        "saturated and marked invalid.",
    )
    frozen_frames: int | None = Field(
        50,
        ge=2,
        le=1_000_000,
        description="This many bit-identical frames in a row mark the sensor frozen: later "
        "identical frames are invalid until the values change (None: no check; a real sensor's "
        "noise makes even two identical frames rare, a noiseless emulator at rest needs None).",
    )

    # -- emulator (port: emulated) -----------------------------------------------------------
    faults: Annotated[FaultValue, FaultKinds(FAULT_KINDS)] = Field(
        "none",
        description="Emulator only: 'none', 'standard' (a mix of the fault matrix at moderate "
        "rates for long runs), or a list of fault events ({kind, at_s | rate_hz, duration_s, "
        "params}).",
    )
    noise_std_n: float = Field(
        0.1, ge=0, le=100.0, description="Emulator: white noise on each force component (N)."
    )
    noise_std_nm: float = Field(
        0.003, ge=0, le=10.0, description="Emulator: white noise on each torque component (N·m)."
    )
    offset_n: Vector3 = Field(
        (0.0, 0.0, 0.0), description="Emulator: constant force offset ε of the sensor (N)."
    )
    lever_arm_m: Vector3 = Field(
        (0.0, 0.0, 0.0),
        description="Emulator: the end effector's centre of mass in the sensor frame; its "
        "inertial and gravity load adds r × f_load to the torque.",
    )
    emulator_firmware: tuple[int, int, int] = Field(
        (3, 0, 1), description="Emulator: the firmware version it reports."
    )

    @model_validator(mode="after")
    def _consistent(self) -> Ft300Config:
        if self.frame_timeout_s <= self.byte_timeout_s:
            raise ValueError(
                f"frame_timeout_s ({self.frame_timeout_s}) must exceed byte_timeout_s "
                f"({self.byte_timeout_s})"
            )
        if self.faults != "none" and not self.emulated:
            raise ValueError("faults are injected by the emulator: they need port 'emulated'")
        return self

    @property
    def emulated(self) -> bool:
        """Whether ``port`` names the emulator."""
        return self.port == EMULATED_PORT
