"""Registration of the ``search`` benchmark suite (import-light: no runner imports)."""

from __future__ import annotations

from collections.abc import Iterator

from hapticframe import BenchSpec, hookimpl

__all__ = ["hapticframe_benchmarks"]


@hookimpl
def hapticframe_benchmarks() -> Iterator[BenchSpec]:
    """Yield the ``search`` suite: the simulated haptic-search study of Table 3.2."""
    yield BenchSpec(
        name="search",
        summary="Haptic search, Table 3.2: two-phase planner vs coverage baseline, circle "
        "and ellipse at random placements.",
        factory="hapticframe_bench._search:run_search",
        install_hint="pip install hapticframe[plots]  (search.png needs matplotlib)",
    )
