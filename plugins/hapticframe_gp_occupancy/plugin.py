"""Registration of the ``gp-occupancy`` map (import-light: no numpy-heavy modules)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, MapSpec, hookimpl

from ._config import GPOccupancyConfig

__all__ = ["hapticframe_maps"]


@hookimpl
def hapticframe_maps() -> Iterator[MapSpec]:
    """Yield the GP occupancy map spec."""
    yield MapSpec(
        name="gp-occupancy",
        summary="Gaussian-process occupancy map (GPOM): GP regression with a probit link, "
                "exact on small sets, inducing points on large ones.",
        config=GPOccupancyConfig,
        factory="hapticframe_gp_occupancy._map:GPOccupancyMap",
        validator="hapticframe_gp_occupancy._checks:check",
        capabilities=frozenset({"continuous", "uncertainty"}),
        requires=("scipy",),
        install_hint="pip install hapticframe  (numpy and scipy); learn_hyperparameters needs "
                     "scikit-learn ('hapticframe[learn]'), figures matplotlib",
        knobs=(
            Knob("method", "'exact' costs O(N³) per refit and O(N) per queried point; "
                 "'inducing' O(N M²) once and O(M²) per point; 'auto' switches at "
                 "exact_max_observations", values=("auto", "exact", "inducing")),
            Knob("exact_max_observations", "a later switch to inducing points: exact for "
                 "longer, each refit cubic in the observations", values=(500, 1000, 2000, 4000)),
            Knob("inducing_spacing_m", "finer inducing points: closer to the exact GP, the "
                 "M points growing as 1/spacing² and each update costing N M²",
                 values=(0.015, 0.02, 0.025, 0.035, 0.05)),
            Knob("length_scale_m", "a longer kernel: smoother maps, blunter outlines",
                 values=(0.02, 0.03, 0.045)),
            Knob("link_scale", "a steeper probit link: sharper probabilities where the data "
                 "agree, worse log loss where they conflict", values=(1.0, 2.0, 3.0, 5.0)),
        ),
    )
