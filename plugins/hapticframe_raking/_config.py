"""Config of the ``raking-estimator`` classifier (import-light: pydantic and hapticframe)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig
from hapticframe.threads import ThreadCount

__all__ = ["DistanceEstimateConfig", "RakingEstimatorConfig"]


class RakingEstimatorConfig(PluginConfig):
    """Distance, direction and depth of a buried object from a tool's tactile forces.

    Streams a ``(4, 3)`` taxel-force channel (4 taxels, x, y, z) and gives at every sample
    the distance to the object with its uncertainty, the direction class probabilities and
    the depth class probabilities (``estimates.npz`` of a run); its class probabilities are
    ``far`` / ``near`` (``near``: P(distance < near_mm)). ``hapticframe train`` fits it on
    recordings whose sensor also carries the label channels (``hapticframe import`` of the
    raking data set gives them).
    """

    input_set: Literal["1_norm", "1_3-axis", "4_norm", "4_3-axis"] = Field(
        "4_3-axis", description="Which taxel forces it reads: one taxel or four, the normal "
        "(z) force only or all three axes (the paper's input sets).")
    force_channel: str = Field("taxel_force", min_length=1,
                               description="Input channel of (4, 3) taxel forces.")
    distance_channel: str = Field("distance_mm", min_length=1,
                                  description="Label channel of the distance (mm), for fit.")
    direction_channel: str = Field("direction_class", min_length=1,
                                   description="Label channel of the direction class (0..2).")
    depth_channel: str = Field("depth_class", min_length=1,
                               description="Label channel of the depth class (0..1).")
    window_steps: int = Field(10, ge=2, le=200, description="Samples each estimate reads.")
    hidden_units: int = Field(32, ge=2, le=512, description="LSTM units.")
    epochs: int = Field(15, ge=1, le=1000)
    batch_size: int = Field(128, ge=1, le=65536)
    learning_rate: float = Field(3e-3, gt=0, le=1, allow_inf_nan=False)
    skip_first_steps: int = Field(
        20, ge=0, le=10_000, description="Steps at the start of each training recording left "
        "out of training (the tool's start-up transient; the authors leave out 20).")
    range_mm: float | None = Field(
        None, gt=0, le=10_000, allow_inf_nan=False, description="Distances beyond this are "
        "learned as this (mm; null: not capped): far from the object the forces do not tell "
        "the distance. bench raking-real-cv chooses it per input set.")
    restart_after_gap_s: float = Field(
        0.5, gt=0, le=1e6, allow_inf_nan=False, description="A pause in the samples longer "
        "than this starts a new window (a new trial; imported trials are 1 s apart).")
    train_threads: ThreadCount = Field(1, description="torch threads while training.")
    near_mm: float = Field(30.0, gt=0, le=10_000, allow_inf_nan=False,
                           description="Distance below which the class is 'near'.")
    model_dir: str | None = Field(None, description="A directory hapticframe train wrote "
                                  "for this component (weights.npz, model.json).")
    pretrained: bool = Field(False, description="Load the model shipped with the plugin "
                             "(trained on the 80 training trials, 4_3-axis, seed 7).")

    @model_validator(mode="after")
    def _one_model(self) -> RakingEstimatorConfig:
        if self.pretrained and self.model_dir is not None:
            raise ValueError("give either 'model_dir' or 'pretrained: true', not both")
        if self.pretrained and self.input_set != "4_3-axis":
            raise ValueError("the shipped model reads input_set '4_3-axis'")
        return self


class DistanceEstimateConfig(PluginConfig):
    """Place each observation at the estimated distance and direction ahead of the tool.

    The weight of each observation says where the estimate is informative: its own
    uncertainty (the estimator's predicted deviation, ``reference_std_m``), whether the
    estimates of the last ``consistency_travel_m`` of travel agree on where the object is
    (``consistency_std_m``), and the travel spacing of reports (``report_spacing_m``).
    """

    direction_bearings_deg: tuple[float, float, float] = Field(
        (-20.0, 0.0, 20.0), description="Bearing of each direction class from the heading "
        "(counter-clockwise, degrees). The raking data set does not say what its classes "
        "mean: these are an assumption.")
    object_weight: float = Field(
        8.0, gt=0, le=1e3, allow_inf_nan=False, description="Weight of each object "
        "observation relative to a free one of the same certainty. Reports come only "
        "from the last centimetres of an approach, where the estimate is certain and "
        "follows the travel, while free reports come from the whole path: at 1 the map "
        "never reached 0.6 on an object it had met from four sides (tuned on bench "
        "search-distance seed 100: 4 found 8 of 10, 8 found 10 of 10, 16 made more "
        "movements).")
    object_depth_m: float = Field(
        0.03, ge=0, le=1, allow_inf_nan=False, description="The estimate is the distance "
        "to the nearest outline point and the object goes on behind it: object "
        "observations at d and at d + object_depth_m along each bearing (0: only at d).")
    max_range_m: float = Field(0.1, gt=0, le=10, allow_inf_nan=False,
                               description="Estimates farther than this place no object.")
    reference_std_m: float = Field(
        0.003, gt=0, le=10, allow_inf_nan=False, description="The estimate's standard "
        "deviation (m) that halves a weight: certainty 1 / (1 + (σ / reference_std_m) ^ "
        "certainty_exponent). In the sandbox an estimate under 3 mm was within 14 mm of "
        "the object (median); one of 3-5 mm was off by 0.2 m: the predicted deviation "
        "tells where the estimate is informative only that sharply.")
    certainty_exponent: float = Field(
        4.0, ge=1, le=64, allow_inf_nan=False, description="How sharply the certainty "
        "falls beyond reference_std_m (2: the Gaussian-product weight s² / (s² + σ²)).")
    free_points: int = Field(3, ge=0, le=100, description="Free observations per sample "
                             "between the tool and the estimate less two deviations.")
    min_weight: float = Field(1e-3, ge=0, le=1, allow_inf_nan=False,
                              description="Observations lighter than this are dropped.")
    fallback_distance_m: float = Field(
        0.03, gt=0, le=10, allow_inf_nan=False, description="Without an estimate (a "
        "classifier that is not an estimator): the fixed distance ahead, as the failure "
        "zone's rupture distance.")
    report_spacing_m: float = Field(
        0.005, ge=0, le=10, allow_inf_nan=False, description="A sample is reported when the "
        "tool's travel since the movement began crosses a multiple of this (m), and always "
        "the first sample of a movement and any sample whose most probable class differs "
        "from the previous one (the halt); 0 reports every sample. At a force sensor's "
        "rate successive estimates are one estimate repeated: counting each as evidence "
        "made blobs of noise.")
    consistency_travel_m: float = Field(
        0.02, ge=0, le=10, allow_inf_nan=False, description="Travel (m) over which the "
        "object points a movement's estimates imply are compared. An object at rest stays "
        "where the estimates put it while the tool moves; an estimate that does not "
        "follow the travel (the same distance repeated: forces that carry no distance) "
        "places no object. Until a movement has travelled this far its estimates count as "
        "not following; 0 turns the check off.")
    consistency_std_m: float = Field(
        0.002, gt=0, le=10, allow_inf_nan=False, description="Spread (m, root mean square "
        "about their mean) of those implied points that halves the weight, falling as "
        "the fourth power beyond (an estimate repeated over 2 cm of travel spreads by "
        "5.8 mm; tuned on bench search-distance seed 100: 2 mm against 3 mm, the same "
        "found rate with fewer interactions).")
    path_free_weight: float = Field(
        0.5, ge=0, le=1, allow_inf_nan=False, description="Weight of the free observation "
        "at the tool's own position at every report (the tool went through there).")
    untracked_free_m: float = Field(
        0.01, ge=0, le=10, allow_inf_nan=False, description="An estimate that does not "
        "follow the travel says the forces carry no distance, so no object is within the "
        "reach where they rise: free observations up to this distance ahead (m), weighted "
        "untracked_free_weight times how little the estimate follows.")
    untracked_free_weight: float = Field(
        0.5, ge=0, le=1, allow_inf_nan=False, description="See untracked_free_m.")
