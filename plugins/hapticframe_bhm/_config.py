"""Configuration of the ``bayesian-hilbert-map`` map (import-light: pydantic only)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig, RegionConfig
from hapticframe.threads import ThreadCount

__all__ = ["BayesianHilbertMapConfig", "length_scale_from_bandwidth_per_cm2"]


def length_scale_from_bandwidth_per_cm2(gamma_per_cm2: float) -> float:
    """Length scale in metres of an RBF bandwidth ``gamma`` in cm^-2: ``sqrt(1/(2 gamma))``."""
    return math.sqrt(1.0 / (2.0 * gamma_per_cm2)) / 100.0


#: Table 3.1 of the thesis: gamma_m = 0.1 cm^-2 for free movement (l = 2.24 cm) and
#: 0.04 cm^-2 for interaction with the object (l = 3.54 cm).
_FREE_LENGTH_SCALE_M = length_scale_from_bandwidth_per_cm2(0.1)
_INTERACTION_LENGTH_SCALE_M = length_scale_from_bandwidth_per_cm2(0.04)


class BayesianHilbertMapConfig(PluginConfig):
    """Settings of the Bayesian Hilbert map (full-covariance variational BHM)."""

    region: RegionConfig | None = Field(
        None,
        description=(
            "Mapped rectangle in metres. Default: the scene's region when the experiment has "
            "a scene, else the thesis's 0.75 x 0.50 m search area."
        ),
    )
    hinge_spacing_m: float = Field(
        0.05,
        gt=0,
        le=10.0,
        description="Spacing of the RBF hinge grid (Table 3.1: 5 cm). Hinges cover the region "
        "with both edges included plus one spacing of padding on every side.",
    )
    length_scale_free_m: float = Field(
        0.033,
        ge=1e-6,
        le=1e3,
        description="Kernel length scale l of hinges in free-movement areas, and of every hinge "
        "when region_dependent_smoothing is off (gamma = 1/(2 l^2)). Default 3.3 cm, about "
        "two thirds of the hinge spacing; Table 3.1's 0.1 cm^-2 gives 2.24 cm.",
    )
    length_scale_interaction_m: float = Field(
        _INTERACTION_LENGTH_SCALE_M,
        ge=1e-6,
        le=1e3,
        description="Kernel length scale of hinges in interaction areas (Table 3.1's "
        "0.04 cm^-2 gives 3.54 cm).",
    )
    region_dependent_smoothing: bool = Field(
        False,
        description="Give hinges near interaction observations, or whose occupancy estimate "
        "exceeds 0.5, the interaction length scale (Table 3.1's two bandwidths; see the "
        "module docstring of hapticframe_bhm._map); false (default) uses "
        "length_scale_free_m everywhere.",
    )
    interaction_radius_m: float = Field(
        0.05,
        ge=0,
        le=10.0, description="A hinge within this distance of an observation with target > 0.5 "
        "switches to the interaction length scale (region_dependent_smoothing only).",
    )
    automorphing_kernels: bool = Field(
        False,
        description="Learn a length scale per hinge from the data (Senanayake and Ramos's "
        "automorphing kernels; see hapticframe_bhm._automorph), starting from "
        "length_scale_free_m. The scales are re-learned on all data whenever the observations "
        "have doubled since the last time (each time costs automorphing_iterations + 1 fits "
        "of all data); batches in between are fused sequentially. Not with "
        "region_dependent_smoothing.",
    )
    automorphing_range: tuple[float, float] = Field(
        (0.5, 2.0),
        description="Smallest and largest learned length scale, as factors of "
        "length_scale_free_m.",
    )
    automorphing_levels: int = Field(
        7, ge=2, le=32,
        description="Learned length scales are rounded to this many log-spaced values over "
        "automorphing_range (few distinct values keep queries fast).",
    )
    automorphing_iterations: int = Field(
        6, ge=1, le=100, description="Ascent steps on the length scales per learning."
    )
    bias: bool = Field(True, description="Append a constant bias feature to the hinge features.")
    prior_variance: float = Field(
        0.45,
        gt=0,
        le=1e8,
        description="Variance of the Gaussian prior of every weight (bias included); small "
        "enough that hinges between sparse observations do not raise spurious blobs "
        "(the reference code's 10 did).",
    )
    prior_occupancy: float = Field(
        0.05,
        gt=0,
        lt=1,
        description="Occupancy of places no observation reaches: the bias weight's prior "
        "mean is logit(prior_occupancy) (0.5: a zero-mean prior). Needs bias.",
    )
    max_iterations_first: int = Field(
        10,
        ge=1,
        le=1000,
        description="Cap on variational EM iterations for the first batch (and for refits).",
    )
    max_iterations_update: int = Field(
        1, ge=1, le=1000,
        description="Cap on variational EM iterations for later batches. 1, as in the public "
        "BHM code: a batch's local parameters start at its prior predictive, where the bound "
        "is already tight, and a second iteration changed the search's maps by less than the "
        "run-to-run spread.",
    )
    tolerance: float = Field(
        0.05,
        gt=0,
        le=1.0, description="Stop iterating when the relative change of the local variational "
        "parameters xi, ||xi_new - xi|| / ||xi||, is at most this.",
    )
    std_method: Literal["surrogate", "monte_carlo"] = Field(
        "surrogate",
        description="Occupancy standard deviation: the deterministic p(1-p) kappa sqrt(var) "
        "(default: no sampling, about 100 times cheaper on a large grid) or the sample std of "
        "sigma(w^T phi) over seeded weight samples (thesis Eq. 3.8).",
    )
    monte_carlo_samples: int = Field(
        100,
        ge=2,
        le=100_000,
        description="Weight samples K for the Monte-Carlo standard deviation.",
    )

    dense_weights_max: int = Field(
        1500,
        ge=2,
        le=5000,
        description="A map with at most this many weights (hinges plus bias) keeps one dense "
        "posterior over its region (the thesis's 75 x 50 cm: 235; 1.5 x 1 m: 760); a larger "
        "one is split into local tiles (see hapticframe_bhm._tiled), so that memory and time "
        "grow with the area observed, not with its square.",
    )
    tile_size_m: float | None = Field(
        None,
        gt=0,
        le=100.0,
        description="Side of a tile's core in a tiled map, rounded to whole hinge spacings; "
        "each tile also holds a halo of hinges two kernel windows wide around its core. "
        "Default: the core is as wide as both halos together (60 cm with 5 cm hinges and "
        "the 3.3 cm length scale), which minimises the dense matrices held per square metre.",
    )
    blas_threads: ThreadCount | None = Field(
        1,
        description="BLAS threads used inside map updates and queries (via threadpoolctl when "
        "installed). The matrices are small (D ~ 235), where one thread is fastest and "
        "avoids oversubscription stalls; null leaves the BLAS setting alone.",
    )

    @model_validator(mode="after")
    def _finite(self) -> BayesianHilbertMapConfig:
        for name in ("hinge_spacing_m", "interaction_radius_m", "tolerance", "tile_size_m"):
            if getattr(self, name) is None:
                continue
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        low, high = self.automorphing_range
        if not (0 < low <= 1.0 <= high <= 100 and math.isfinite(high)):
            raise ValueError("automorphing_range must be (low, high) with 0 < low <= 1 <= high "
                             "<= 100")
        if self.automorphing_kernels and self.region_dependent_smoothing:
            raise ValueError("automorphing_kernels and region_dependent_smoothing exclude each "
                             "other: choose one way of setting the length scales")
        return self
