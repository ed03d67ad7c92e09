"""``bench bhm``'s rows for ``gp-occupancy`` beside the BHM (issue 19 §2)."""

from __future__ import annotations

import pytest

from hapticframe_bench._bhm import _gp_lines, benchmark_gp_scaling, crossover


def test_crossover_interpolates_where_the_ratio_rises_through_one() -> None:
    assert crossover([(100, 0.5), (1000, 2.0)]) == {"observations": 316, "how": "between"}
    assert crossover([(100, 0.2), (1000, 0.8), (10_000, 3.2)])["observations"] == 1449
    assert crossover([(100, 1.5), (1000, 9.0)]) == {"observations": 100, "how": "below"}
    assert crossover([(100, 0.5), (1000, 0.9)]) == {"observations": None, "how": "beyond"}
    assert crossover([])["how"] == "not measured"


def test_the_scaling_rows_time_and_score_every_map() -> None:
    result = benchmark_gp_scaling(rng_seed=0, repeats=1, sizes=(120, 240), exact_max=120,
                                  exact_grid_max=120, grid_spacing_m=0.025)
    rows = {(r["map"], r["observations"]): r for r in result["rows"]}
    assert set(rows) == {("bhm", 120), ("gp-inducing", 120), ("gp-inducing-5cm", 120),
                         ("gp-exact", 120), ("bhm", 240), ("gp-inducing", 240),
                         ("gp-inducing-5cm", 240)}
    for row in rows.values():
        assert row["fit_ms"] > 0 and row["query_1000_ms"] > 0 and row["grid_15000_ms"] > 0
        # Few observations, but the two objects cover 4 % of the region: better than chance.
        assert 0.7 < row["auc"] <= 1.0
        assert 0.0 < row["log_loss"] < 0.69
    # The exact GP and DTC on a 2.5 cm grid agree closely on 120 points.
    assert rows[("gp-exact", 120)]["auc"] == pytest.approx(rows[("gp-inducing", 120)]["auc"],
                                                           abs=0.02)
    assert set(result["crossover"]) == {f"{m}:{t}" for m in
                                        ("gp-exact", "gp-inducing", "gp-inducing-5cm")
                                        for t in ("fit_ms", "query_1000_ms", "grid_15000_ms")}
    lines = _gp_lines(result)
    assert lines[0] == "## GP occupancy against the BHM (issue 19 §2)"
    assert sum(line.startswith("| 120 |") for line in lines) == 4
    assert any(line.startswith("- gp-exact, fit: ") for line in lines)
