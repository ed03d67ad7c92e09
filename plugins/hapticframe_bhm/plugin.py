"""Registration of the ``bayesian-hilbert-map`` map (import-light: no numpy-heavy modules)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import Knob, MapSpec, hookimpl

from ._config import BayesianHilbertMapConfig

__all__ = ["hapticframe_maps"]


@hookimpl
def hapticframe_maps() -> Iterator[MapSpec]:
    """Yield the Bayesian Hilbert map spec."""
    yield MapSpec(
        name="bayesian-hilbert-map",
        summary="Continuous occupancy map with uncertainty: full-covariance variational BHM.",
        config=BayesianHilbertMapConfig,
        factory="hapticframe_bhm._map:BayesianHilbertMap",
        validator="hapticframe_bhm._checks:check",
        capabilities=frozenset({"continuous", "uncertainty"}),
        requires=("scipy",),
        install_hint="pip install hapticframe  (numpy and scipy); figures need matplotlib",
        knobs=(
            Knob("hinge_spacing_m", "finer hinges: a sharper outline; the D hinges grow as "
                 "1/spacing² and each update costs D³", values=(0.025, 0.035, 0.05, 0.075, 0.1)),
            Knob("max_iterations_update", "more EM iterations per batch: a tighter posterior, "
                 "each one a full update", values=(1, 2, 5)),
            Knob("tolerance", "a looser stopping rule: fewer EM iterations, a looser fit",
                 low=0.005, high=0.2, scale="log", points=4),
            Knob("std_method", "'surrogate': a deterministic std about 100 times cheaper on "
                 "a large grid than the sampled one of Eq. 3.8",
                 values=("surrogate", "monte_carlo")),
        ),
    )

