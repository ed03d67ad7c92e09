"""Registration of the force observer feature extractor (import-light)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, FeatureExtractorSpec, Knob, hookimpl

from ._config import ForceObserverConfig


@hookimpl
def hapticframe_feature_extractors() -> Iterator[FeatureExtractorSpec]:
    yield FeatureExtractorSpec(
        name="force-observer",
        summary="Environment force from a wrist F/T sensor and an IMU: the end effector's "
        "inertia, gravity and offset removed (Eq. 3.10).",
        config=ForceObserverConfig,
        factory="hapticframe_force_observer._observer:ForceObserver",
        validator="hapticframe_force_observer._checks:check",
        capabilities=frozenset({"trainable"}),
        requires=("scipy",),
        consumes={
            "force_n": ChannelSpec((3,), "N", "the wrist wrench's force, all three axes"),
            "acceleration_m_per_s2": ChannelSpec((3,), "m/s^2", "the IMU's, gravity included"),
        },
        produces={"force_n": ChannelSpec(
            (3,), "N", "the environment's force on the tool (Eq. 3.10), world frame")},
        sample_rate_hz=100.0,
        # A real load (0.8 kg, IMU turned 45° about y, an offset), so the kit's checks run
        # the whole of Eq. 3.10 rather than the pass-through defaults.
        check_config={
            "mass_kg": 0.8,
            "imu_rotation_wxyz": [0.9238795325112867, 0.0, 0.3826834323650898, 0.0],
            "bias_n": [0.5, -0.2, 1.0],
        },
        knobs=(
            Knob("cutoff_hz", "a higher low-pass cutoff: the environment force sooner, more "
                 "sensor and inertial noise in it", values=(5.0, 10.0, 20.0, 40.0)),
            Knob("filter_order", "a higher filter order: sharper noise rejection, more group "
                 "delay", values=(1, 2, 4)),
        ),
    )
