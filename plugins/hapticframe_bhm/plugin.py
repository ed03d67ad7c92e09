"""Registration of the ``bayesian-hilbert-map`` map (import-light: no numpy-heavy modules)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import MapSpec, hookimpl

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
    )

