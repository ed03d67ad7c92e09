"""Registration of the BioTac fingertip sensor (import-light: config model and hapticframe only)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, SensorSpec, hookimpl

from ._config import BioTacSensorConfig

__all__ = ["SPECS", "hapticframe_sensors"]

#: The specs this package registers (for the conformance kit and tests).
SPECS = (
    SensorSpec(
        name="biotac",
        produces={
            "pac": ChannelSpec((22,), "count", "AC pressure, 22 samples per frame"),
            "pdc": ChannelSpec((), "count", "DC pressure"),
            "tac": ChannelSpec((), "count", "AC temperature"),
            "tdc": ChannelSpec((), "count", "DC temperature"),
            "electrodes": ChannelSpec((None,), "count", "impedance electrodes (19; 24 on the SP)"),
        },
        summary=(
            "SynTouch BioTac / BioTac SP frames from synthetic trials, recordings or the SPI "
            "word stream."
        ),
        config=BioTacSensorConfig,
        factory="hapticframe_biotac._sensor:BioTacSensor",
        validator="hapticframe_biotac._checks:check",
        capabilities=frozenset({"finite"}),
        inputs=(),
        # The emulated SPI stream needs no files and exercises the decoder with every fault kind.
        check_config={
            "source": "spi",
            "spi_backend": "emulator",
            "emulator_frames": 150,
            "frames_per_read": 2,
            "parity_error_rate": 0.002,
            "stale_word_rate": 0.001,
            "dropped_frame_rate": 0.02,
        },
    ),
)


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield from SPECS
