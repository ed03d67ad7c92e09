"""Configuration of the ``gp-occupancy`` map (import-light: pydantic and the standard library)."""

from __future__ import annotations

import math
from statistics import NormalDist
from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig, RegionConfig
from hapticframe.threads import ThreadCount

__all__ = ["GPOccupancyConfig", "prior_latent_mean"]


def prior_latent_mean(occupancy: float, link_scale: float, signal_variance: float) -> float:
    """The GP's constant prior mean ``m0`` whose occupancy through the link is ``occupancy``
    (as :func:`hapticframe_gp_occupancy._functional.prior_mean_for_occupancy`)."""
    return NormalDist().inv_cdf(occupancy) * math.sqrt(1.0 + link_scale**2 * signal_variance) / (
        link_scale)


class GPOccupancyConfig(PluginConfig):
    """Gaussian-process occupancy map (GPOM): GP regression on the targets, probit link."""

    region: RegionConfig | None = Field(
        None,
        description=(
            "Mapped rectangle in metres (where inducing points lie and figures are drawn). "
            "Default: the scene's region when the experiment has a scene, else the thesis's "
            "0.75 x 0.50 m search area."
        ),
    )
    method: Literal["auto", "exact", "inducing"] = Field(
        "auto",
        description="'exact': the full GP (O(N^3) in the observations N); 'inducing': the "
        "DTC approximation on a grid of inducing points (O(N M^2)); 'auto' (default): exact "
        "while N is at most exact_max_observations, inducing beyond.",
    )
    exact_max_observations: int = Field(
        2000,
        ge=1,
        le=20_000,
        description="Most observations (of positive weight) the exact GP takes under 'auto'. "
        "The exact kernel matrix holds N^2 doubles: 2,000 is 32 MB, 20,000 is 3.2 GB.",
    )
    inducing_spacing_m: float = Field(
        0.025,
        gt=0,
        le=10.0,
        description="Spacing of the grid of inducing points over the region (edges included). "
        "At most about the length scale: coarser grids blur the outline.",
    )
    length_scale_m: float = Field(
        0.03, ge=1e-4, le=100.0,
        description="Length scale l of the squared-exponential kernel (the BHM's default "
        "features have 3.3 cm).",
    )
    signal_variance: float = Field(
        1.0, gt=0, le=1e4, description="Prior variance of the latent occupancy f."
    )
    noise_variance: float = Field(
        0.25,
        gt=0,
        le=1e4,
        description="Noise variance of a target of weight 1 on the latent scale (targets are "
        "2y - 1: 1 occupied, -1 free); an observation of weight w has noise_variance / w.",
    )
    link_scale: float = Field(
        3.0,
        gt=0,
        le=100.0,
        description="Slope alpha of the probit link p = E[Phi(alpha f)]: larger values give "
        "sharper probabilities where the data agree.",
    )
    prior_occupancy: float = Field(
        0.5,
        gt=0,
        lt=1,
        description="Occupancy where no observation reaches (sets the GP's constant prior "
        "mean); 0.5 is uninformed.",
    )
    learn_hyperparameters: bool = Field(
        False,
        description="Learn length scale, signal and noise variance by maximising the marginal "
        "likelihood (scikit-learn's GaussianProcessRegressor, L-BFGS-B from the configured "
        "values) whenever the map is refitted exactly; the inducing path keeps the last "
        "learned values.",
    )
    max_inducing_points: int = Field(
        4000,
        ge=4,
        le=10_000,
        description="Most inducing points (the DTC posterior is a dense M x M matrix); a "
        "region and spacing giving more are refused.",
    )
    blas_threads: ThreadCount | None = Field(
        1,
        description="BLAS threads used in updates and queries (via threadpoolctl when "
        "installed); null leaves the BLAS setting alone.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> GPOccupancyConfig:
        for name in ("inducing_spacing_m", "length_scale_m", "signal_variance",
                     "noise_variance", "link_scale"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite")
        m0 = prior_latent_mean(self.prior_occupancy, self.link_scale, self.signal_variance)
        if not -1.0 < m0 < 1.0:
            raise ValueError(
                f"prior_occupancy {self.prior_occupancy:g} needs a prior mean of {m0:.3g} on "
                "the latent scale, beyond the targets of free (-1) and occupied (1) "
                "observations: a free observation would then raise the occupancy. Move "
                "prior_occupancy towards 0.5, or raise link_scale or lower signal_variance"
            )
        return self
