"""SynTouch BioTac fingertip: frame layout, SPI wire decoding, an emulator, replay, and the sensor.

Registers the sensor ``biotac``. Public beyond the sensor: the frame layout
(:class:`BioTacFrames`, :func:`layout_for`), the tares (:func:`tare_frames` on a
recording's own first frames, :func:`tare_in_air` on frames taken in open air), and the
synthetic granular-media generator of dissertation §2.6 (:class:`TrialSpec`,
:func:`generate_trial`, :func:`training_specs`, :func:`robustness_specs`,
:func:`open_air_frames`, :func:`frame_features`, :func:`generate_open_air_trial`,
:func:`contact_interval_x_m`, :func:`granular_noise_ratios`), which the perception benchmark
(``hapticframe_bench``) and the tests build their datasets from.
Real recordings: the Penn BOLT HDF5 layout (:func:`load_bolt`, :func:`load_bolt_dir`,
:func:`rebuild_frame_clock`, :func:`save_bolt`), the contact reference derived from pdc
(:func:`derived_from_pdc`, :class:`PdcReference`), and the calibration of a synthetic press
generator on them (:func:`calibrate_biotac`, :class:`BioTacCalibration`,
:func:`generate_press_trial`); see ``docs/real-biotac.md``.
A real SPI adapter is a separate package that registers a backend factory by name in the
``hapticframe.biotac_spi`` entry-point group (see ``_backends``). Importing this package is
cheap; the implementation modules load on first attribute access.
"""

from __future__ import annotations

from hapticframe import lazy_exports

from ._config import BioTacSensorConfig

__all__ = [
    "DERIVED_FROM_PDC",
    "PAC_BANDS_HZ",
    "BioTacCalibration",
    "BioTacFrames",
    "BioTacSensor",
    "BoltTrial",
    "BioTacSensorConfig",
    "EmulatedBioTac",
    "FaultPlan",
    "FrameLayout",
    "Recording",
    "ReplayFormatError",
    "SpiBatchBackend",
    "Trial",
    "TrialSpec",
    "WordStreamDecoder",
    "PdcReference",
    "calibrate_biotac",
    "contact_interval_x_m",
    "derived_from_pdc",
    "encode_frames",
    "frame_features",
    "generate_open_air_trial",
    "generate_press_trial",
    "generate_trial",
    "granular_noise_ratios",
    "layout_for",
    "load_bolt",
    "load_bolt_dir",
    "load_csv",
    "load_npz",
    "load_recording",
    "open_air_frames",
    "rebuild_frame_clock",
    "robustness_specs",
    "save_bolt",
    "save_npz",
    "schedule_for",
    "tare_frames",
    "tare_in_air",
    "training_specs",
]

_LAZY = {
    "BioTacFrames": "._frame",
    "FrameLayout": "._frame",
    "layout_for": "._frame",
    "BioTacSensor": "._sensor",
    "tare_frames": "._sensor",
    "tare_in_air": "._sensor",
    "EmulatedBioTac": "._emulator",
    "FaultPlan": "._emulator",
    "SpiBatchBackend": "._emulator",
    "WordStreamDecoder": "._wire",
    "encode_frames": "._wire",
    "schedule_for": "._wire",
    "Recording": "._replay",
    "ReplayFormatError": "._replay",
    "load_csv": "._replay",
    "load_npz": "._replay",
    "load_recording": "._replay",
    "save_npz": "._replay",
    "BoltTrial": "._bolt",
    "load_bolt": "._bolt",
    "load_bolt_dir": "._bolt",
    "rebuild_frame_clock": "._bolt",
    "save_bolt": "._bolt",
    "DERIVED_FROM_PDC": "._reference",
    "PdcReference": "._reference",
    "derived_from_pdc": "._reference",
    "BioTacCalibration": "._calibration",
    "PAC_BANDS_HZ": "._calibration",
    "calibrate_biotac": "._calibration",
    "generate_press_trial": "._synthetic_press",
    # the synthetic granular-media generator (its own module, numpy-heavy)
    "Trial": "._synthetic",
    "TrialSpec": "._synthetic",
    "generate_trial": "._synthetic",
    "training_specs": "._synthetic",
    "robustness_specs": "._synthetic",
    "open_air_frames": "._synthetic",
    "frame_features": "._synthetic",
    "generate_open_air_trial": "._synthetic",
    "contact_interval_x_m": "._synthetic",
    "granular_noise_ratios": "._synthetic",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY)
