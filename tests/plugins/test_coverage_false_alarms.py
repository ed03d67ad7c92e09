"""The two-phase planner against false alarms and objects between its lines (issue 32 §5):
``reverse_confirms`` and ``phase1_second_pass``."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from hapticframe import RegionConfig
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    Map,
    MapEstimate,
    MovementResult,
    Observations,
    Region,
    RobotState,
)
from hapticframe_coverage import TwoPhaseCoverage, TwoPhaseCoverageConfig

BOX = (0.0, 0.75, 0.0, 0.50)


class BlankMap(Map):
    """A map that knows nothing (the planner's geometry is what is tested)."""

    def __init__(self) -> None:
        super().__init__(None, BuildContext("blank", np.random.default_rng(0)))

    @property
    def region(self) -> Region:
        return Region(*BOX)

    def update(self, observations: Observations) -> None:
        pass

    def query(self, points_m) -> MapEstimate:
        n = len(np.asarray(points_m, dtype=float).reshape(-1, 2))
        return MapEstimate(np.full(n, 0.1), np.full(n, 0.3))


def planner(**config: object) -> TwoPhaseCoverage:
    return TwoPhaseCoverage(
        TwoPhaseCoverageConfig.model_validate({"region": RegionConfig(), **config}),
        BuildContext("plan", np.random.default_rng(3), {"bhm": BlankMap()}),
    )


def _end(p: TwoPhaseCoverage, i: int, movement: ExploratoryMovement, halt_at: float | None
         ) -> MovementResult:
    """End ``movement``: halted at fraction ``halt_at`` of its length (an interaction)."""
    if halt_at is None:
        where, halted = movement.end_m, False
    else:
        where = movement.start_m + halt_at * (movement.end_m - movement.start_m)
        halted = True
    result = MovementResult(i, movement, halted, "interaction" if halted else "",
                            RobotState(float(i), where, movement.heading_rad),
                            "jamming" if halted else "free")
    p.on_movement_end(result)
    return result


def test_an_unconfirmed_report_is_dropped_and_phase_1_goes_on() -> None:
    p = planner(reverse_confirms=True)
    first = p.propose()
    _end(p, 0, first, 0.4)  # a false alarm 40 % along the first line
    reverse = p.propose()
    assert reverse is not None and np.allclose(reverse.start_m, first.end_m)
    _end(p, 1, reverse, None)  # the far end meets nothing
    assert p.phase == "phase1" and p.interaction_points == []
    following = p.propose()
    assert following is not None and following.phase == "phase1"
    assert not np.allclose(following.start_m, first.start_m)  # the next line


def test_a_confirmed_report_starts_phase_2_and_without_the_option_any_does() -> None:
    for confirms, reverse_meets in ((True, 0.5), (False, None)):
        p = planner(reverse_confirms=confirms)
        _end(p, 0, p.propose(), 0.4)
        _end(p, 1, p.propose(), reverse_meets)
        assert p.phase == "phase2"
        assert len(p.interaction_points) == (2 if reverse_meets else 1)


def _rake_everything(p: TwoPhaseCoverage) -> list[ExploratoryMovement]:
    raked = []
    for i in range(100):
        movement = p.propose()
        if movement is None:
            return raked
        raked.append(movement)
        _end(p, i, movement, None)
    raise AssertionError("the planner kept proposing")


def _offsets(movements: list[ExploratoryMovement]) -> list[float]:
    """Each line's offset along its normal (lines of one direction)."""
    out = []
    for m in movements:
        u = np.array([np.cos(m.heading_rad), np.sin(m.heading_rad)])
        out.append(float(np.round(m.start_m @ np.array([-u[1], u[0]]), 9)))
    return out


def test_the_second_pass_across_rakes_the_lines_at_right_angles_once() -> None:
    plain = _rake_everything(planner())
    crossed = _rake_everything(planner(phase1_second_pass="across"))
    # The first pass is unchanged.
    assert [(tuple(m.start_m), tuple(m.end_m)) for m in crossed[:len(plain)]] == [
        (tuple(m.start_m), tuple(m.end_m)) for m in plain]
    extra = crossed[len(plain):]
    assert extra, "no second pass"
    first = np.degrees(plain[0].heading_rad) % 180.0
    for movement in extra:
        assert abs((np.degrees(movement.heading_rad) - first) % 180.0 - 90.0) < 1e-6
    # 10 cm lines across the 75 x 50 cm region: 5 one way and 8 the other.
    assert sorted((len(plain), len(extra))) == [5, 8]


def test_the_second_pass_between_rakes_midway_between_the_first_lines() -> None:
    plain = _rake_everything(planner())
    between = _rake_everything(planner(phase1_second_pass="between"))
    extra = between[len(plain):]
    assert len(extra) == len(plain) - 1
    first, second = sorted(abs(v) for v in _offsets(plain)), sorted(
        abs(v) for v in _offsets(extra))
    # Each new line lies midway between two neighbours of the first pass.
    assert second == pytest.approx([(a + b) / 2 for a, b in itertools.pairwise(first)])
    assert all(abs(np.sin(m.heading_rad - plain[0].heading_rad)) < 1e-9 for m in extra)


def test_parallel_lines_between_lie_on_the_strip_borders() -> None:
    from hapticframe_coverage._functional import parallel_lines

    starts, _ = parallel_lines(BOX, 0.0, 0.1)
    mid, _ = parallel_lines(BOX, 0.0, 0.1, between=True)
    assert np.allclose(starts[:, 1], [0.05, 0.15, 0.25, 0.35, 0.45])
    assert np.allclose(mid[:, 1], [0.1, 0.2, 0.3, 0.4])
    single, _ = parallel_lines(BOX, 0.0, 1.0, between=True)
    assert single.shape == (0, 2)  # one strip: no border inside
