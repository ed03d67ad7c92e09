"""Registration of the force/force-rate jamming classifier (import-light)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import ChannelSpec, ClassifierSpec, Knob, hookimpl

from ._config import ForceRateJammingConfig
from ._drag_config import DragRatioJammingConfig


@hookimpl
def hapticframe_classifiers() -> Iterator[ClassifierSpec]:
    yield ClassifierSpec(
        name="force-rate-jamming",
        summary="Free / granular jamming / contact from filtered force and force rate (Fig. 3.4).",
        config=ForceRateJammingConfig,
        factory="hapticframe_jamming._classifier:ForceRateJammingClassifier",
        validator="hapticframe_jamming._checks:check",
        capabilities=frozenset({"trainable"}),
        requires=("scipy",),
        # |F| of whatever components the force has: the sandbox's 2 in-plane ones, a wrist
        # sensor's or the force observer's 3 (docs/plugin-authoring.md, channel contracts).
        consumes={"force_n": ChannelSpec(
            (None,), "N", "uses |F|, the Euclidean norm over all its components", example=(2,))},
        sample_rate_hz=100.0,
        knobs=(
            Knob("cutoff_hz", "a higher low-pass cutoff: jamming and contact detected sooner, "
                 "noise read as force rate", values=(1.5, 3.0, 6.0, 10.0)),
            Knob("filter_order", "a higher filter order: sharper noise rejection, more group "
                 "delay before a detection", values=(1, 2, 4)),
        ),
    )
    yield ClassifierSpec(
        name="drag-ratio-jamming",
        summary="Free / jamming / contact from force relative to the movement's own free drag "
        "(CUSUM on log force/drag; contact on the ratio and its rate).",
        config=DragRatioJammingConfig,
        factory="hapticframe_jamming._drag_classifier:DragRatioJammingClassifier",
        validator="hapticframe_jamming._checks:check",
        capabilities=frozenset({"trainable"}),
        requires=("scipy",),
        consumes={"force_n": ChannelSpec(
            (None,), "N", "uses |F| over all its components, or the one named by "
            "force_component", example=(2,))},
        sample_rate_hz=100.0,
        knobs=(
            Knob("drift", "a larger drift: fewer false alarms in free sand, jamming flagged "
                 "later (nearer the object)", values=(0.05, 0.12, 0.25)),
            Knob("cusum_threshold", "a higher CUSUM level: fewer false alarms, later "
                 "detection", values=(0.0, 0.02, 0.1)),
        ),
    )
