"""Configuration of the ``contact-point`` sensor model and the ``belief-map`` map.

Import-light (pydantic and hapticframe only): these models are imported to validate
experiment files and write JSON Schemas, where scikit-learn and matplotlib must not load.
"""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from hapticframe import PluginConfig, RegionConfig

__all__ = ["BeliefMapConfig", "ContactPointConfig"]


class ContactPointConfig(PluginConfig):
    """One map observation per located classifier sample, at the fingertip (Jia 2022, §2.5)."""

    contact_class: str = Field(
        "contact",
        min_length=1,
        description=(
            "Name of the classifier class that means 'fingertip touches the buried object'; its "
            "probability becomes the observation target."
        ),
    )
    class_targets: dict[str, float] | None = Field(
        None,
        description=(
            "Optional mapping from class name to the occupancy target that class stands for, "
            "for classifiers with more than two classes (e.g. {'contact': 1.0, 'jamming': 1.0} "
            "counts jamming as contact). The target is then sum_k p_k * value_k over the named "
            "classes; unnamed classes count 0. When given it replaces contact_class."
        ),
    )

    @model_validator(mode="after")
    def _valid_targets(self) -> ContactPointConfig:
        if self.class_targets is not None:
            if not self.class_targets:
                raise ValueError("class_targets must name at least one class")
            for name, value in self.class_targets.items():
                if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                    raise ValueError(f"class_targets[{name!r}] must lie in [0, 1], got {value}")
        return self


class BeliefMapConfig(PluginConfig):
    """RBF support-vector classification with Platt scaling over fingertip positions (App. A.4)."""

    region: RegionConfig | None = Field(
        None,
        description=(
            "Mapped rectangle in metres. Default: the scene's region when the experiment has one; "
            "otherwise the extent of the observed positions plus region_margin_m (a synthetic "
            "BioTac trial covers only ~12.5 cm); before any observation, the thesis's "
            "0.75 x 0.50 m search area."
        ),
    )
    region_margin_m: float = Field(
        0.05,
        ge=0.0,
        le=100.0,
        description="Margin added on every side of the observed extent when no region is given.",
    )
    length_scale_m: float = Field(
        0.02,
        gt=0.0,
        le=100.0,
        description=(
            "RBF length scale l; the kernel width is gamma = 1 / (2 l^2) (Eq. A.9). 2 cm turns a "
            "5.4 cm contact chord into a high-probability region of about 10 cm, as Fig. 2.7c."
        ),
    )
    penalty_c: float = Field(
        1.0, gt=0.0, le=1e6, description="SVC penalty C (per unit of observation weight)."
    )
    cell_size_m: float = Field(
        0.002,
        gt=0.0,
        le=10.0,
        description=(
            "Edge of the square bins that bound the update cost: observations are summed per "
            "(cell, decided class) into a weight and a weighted mean position, and the SVC is "
            "fitted on these representatives with their weights as sample weights."
        ),
    )
    max_points: int = Field(
        400,
        ge=4,
        le=100_000,
        description=(
            "Most (cell, class) representatives kept. When exceeded, the cell size doubles (cells "
            "merge exactly) until the set fits, so a refit never sees more than this many points."
        ),
    )
    update_every: int = Field(
        10,
        ge=1,
        le=1_000_000,
        description=(
            "Refit the classifier once this many observations (one per classifier step for "
            "contact-point) have arrived since the last refit; the thesis refits every 10 steps."
        ),
    )
    calibration_folds: int = Field(
        3,
        ge=2,
        le=20,
        description=(
            "Cross-validation folds for Platt scaling (CalibratedClassifierCV cv); reduced to the "
            "size of the smaller class when that has fewer representatives (at least 2 needed)."
        ),
    )
    unexplored_prior: float | None = Field(
        0.5,
        ge=0.0,
        le=1.0,
        description=(
            "Probability the map returns far from every observation (the uniform prior of App. "
            "A.4). The SVC/Platt probability p is blended as w p + (1 - w) prior with w = "
            "exp(-d^2 / (2 l^2)), d the distance to the nearest observation bin. Without it an SVC "
            "returns sigmoid(A b + B) far away, which follows the class balance (0.7 after a trial "
            "that was mostly contact). null: no blending."
        ),
    )
    max_snapshots: int = Field(
        64,
        ge=4,
        le=10_000,
        description=(
            "Fitted maps kept after first contact to pick the mid-contact snapshot from; when "
            "full, every other interior one is dropped (first and newest kept)."
        ),
    )

    @model_validator(mode="after")
    def _finite(self) -> BeliefMapConfig:
        for name in ("region_margin_m", "length_scale_m", "penalty_c", "cell_size_m"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        return self

    @property
    def gamma_per_m2(self) -> float:
        """The RBF gamma, ``1 / (2 l^2)`` in 1/m^2."""
        return 1.0 / (2.0 * self.length_scale_m**2)
