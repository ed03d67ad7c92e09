"""A closed loop that looks ahead (``run.lookahead_steps``) gives the step-by-step results.

The loop simulates a batch of robot steps, classifies them at once and, when the batch holds
an interaction, rewinds the robot, sensor and classifier and replays it one step at a time.
Everything it records must be bit for bit what the one-step loop records.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe import RunSettings, run_experiment, validate_mapping
from hapticframe.kinds import BuildContext, SampleBatch
from hapticframe_bench import search_experiment
from hapticframe_bhm import BayesianHilbertMap
from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig
from hapticframe_sandbox import SandboxRobot

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = [{"shape": "circle", "center_m": [0.22, 0.31], "radius_m": 0.04}]


def _experiment(
    planner: str, lookahead: int, every: int = 0, movements: int = 8, objects: list = CIRCLE
) -> dict:
    data = search_experiment(objects, planner, 3, f"lookahead-{lookahead}")
    data["run"].update(figures=False, lookahead_steps=lookahead, map_update_every_steps=every,
                       max_movements=movements)
    return data


def _run(tmp_path: Path, name: str, data: dict) -> tuple[dict, dict, list[str]]:
    lines: list[str] = []
    out = tmp_path / name
    metrics = run_experiment(validate_mapping(data, source=name), out, echo=lines.append)
    with np.load(out / "trace.npz", allow_pickle=False) as trace:
        arrays = {k: trace[k] for k in trace.files}
    return metrics, arrays, [line for line in lines if line.startswith("EM ")]


def _assert_same_run(a: tuple[dict, dict, list[str]], b: tuple[dict, dict, list[str]]) -> None:
    (m1, t1, p1), (m2, t2, p2) = a, b
    assert list(t1) == list(t2)
    for key in t1:
        assert t1[key].dtype == t2[key].dtype and t1[key].shape == t2[key].shape, key
        assert np.array_equal(t1[key], t2[key], equal_nan=t1[key].dtype.kind == "f"), key
    timing = {"wall_time_s"}
    assert {k: v for k, v in m1.items() if k not in timing} == {
        k: v for k, v in m2.items() if k not in timing}
    assert p1 == p2


@pytest.fixture
def counted_rewinds(monkeypatch):
    calls = {"rewind": 0, "batch_rows": []}
    rewind, update = SandboxRobot.rewind, ForceRateJammingClassifier.update

    def counting_rewind(self, checkpoint):  # type: ignore[no-untyped-def]
        calls["rewind"] += 1
        return rewind(self, checkpoint)

    def recording_update(self, batch):  # type: ignore[no-untyped-def]
        calls["batch_rows"].append(len(batch))
        return update(self, batch)

    monkeypatch.setattr(SandboxRobot, "rewind", counting_rewind)
    monkeypatch.setattr(ForceRateJammingClassifier, "update", recording_update)
    return calls


def test_two_phase_search_is_the_same_with_and_without_lookahead(tmp_path, counted_rewinds):
    # Four movements: phase 1's halted line and its reverse, two halted phase-2 sweeps.
    stepwise = _run(tmp_path, "one", _experiment("two-phase-coverage", 1, movements=4))
    assert max(counted_rewinds["batch_rows"]) == 1 and counted_rewinds["rewind"] == 0
    counted_rewinds["batch_rows"].clear()
    ahead = _run(tmp_path, "ahead", _experiment("two-phase-coverage", 64, movements=4))
    _assert_same_run(stepwise, ahead)
    # The batched path really ran, and interactions were found inside batches and replayed.
    assert max(counted_rewinds["batch_rows"]) == 64
    assert counted_rewinds["rewind"] >= 1 and stepwise[0]["object_interactions"] >= 1
    assert sum(" phase2 " in line for line in stepwise[2]) == 2


def test_batches_end_where_maps_are_updated_mid_movement(tmp_path, monkeypatch):
    # Three coverage lines, the second and third halted by a circle on them (batches holding
    # the interaction are rewound): maps are updated every 25 steps inside each movement,
    # so batches of 16 must stop short at 25, 50, ... for the maps to get the same updates.
    # The maps' results alone do not show it (grouped updates gave the same trace).
    updates: list[int] = []
    update = BayesianHilbertMap.update

    def recording_update(self, observations):  # type: ignore[no-untyped-def]
        updates.append(len(observations))
        return update(self, observations)

    monkeypatch.setattr(BayesianHilbertMap, "update", recording_update)
    on_lines = [{"shape": "circle", "center_m": [0.40, 0.10], "radius_m": 0.04}]
    stepwise = _run(tmp_path, "one", _experiment("coverage", 1, 25, 3, on_lines))
    stepwise_updates = updates.copy()
    updates.clear()
    ahead = _run(tmp_path, "ahead", _experiment("coverage", 16, 25, 3, on_lines))
    _assert_same_run(stepwise, ahead)
    assert updates == stepwise_updates
    assert len(updates) > 20 * stepwise[0]["movements"]  # many updates inside movements
    assert stepwise[0]["object_interactions"] >= 1


def test_a_component_that_cannot_rewind_keeps_the_loop_one_step_at_a_time(
    tmp_path, monkeypatch, counted_rewinds
):
    monkeypatch.setattr(ForceRateJammingClassifier, "checkpoint", lambda self: None)
    _run(tmp_path, "no-rewind", _experiment("two-phase-coverage", 64, movements=4))
    assert set(counted_rewinds["batch_rows"]) == {1} and counted_rewinds["rewind"] == 0


def test_lookahead_setting_is_validated():
    assert RunSettings().lookahead_steps > 1
    with pytest.raises(ValueError):
        RunSettings(lookahead_steps=0)


def _classifier() -> ForceRateJammingClassifier:
    return ForceRateJammingClassifier(
        ForceRateJammingConfig(), BuildContext("jam", np.random.default_rng(0))
    )


def test_jamming_batches_equal_one_sample_updates_bit_for_bit():
    rng = np.random.default_rng(7)
    n = 300
    t = 0.01 * np.arange(1, n + 1)
    # Free drag, then a surge of 0.6 N per 10 ms (60 N/s) from sample 200 on.
    surge = 0.6 * np.maximum(0, np.arange(n) - 200)
    force = np.column_stack([-(5 + surge + rng.normal(0, 0.3, n)), rng.normal(0, 0.3, n)])
    force[40] = np.nan  # sample-and-hold path
    valid = np.ones(n, dtype=bool)
    valid[90:93] = False
    batch = SampleBatch(t, {"force_n": force}, {"force_n": valid})
    one_by_one = _classifier()
    rows = np.vstack([one_by_one.update(batch.select(slice(i, i + 1))).probabilities
                      for i in range(n)])
    batched = _classifier()
    chunks = [batched.update(batch.select(slice(s, s + 37))).probabilities
              for s in range(0, n, 37)]
    assert np.array_equal(np.vstack(chunks), rows)  # exact, not merely close
    labels = np.argmax(rows, axis=1)
    assert labels[:200].max() == 0 and labels.max() >= 1  # the surge reads as jamming


def test_jamming_classifier_rewinds_its_filter():
    rng = np.random.default_rng(8)
    t = 0.01 * np.arange(1, 201)
    batch = SampleBatch(t, {"force_n": rng.normal(10, 2, (200, 2))})
    clf = _classifier()
    clf.update(batch.select(slice(0, 50)))
    snapshot = clf.checkpoint()
    first = clf.update(batch.select(slice(50, 120))).probabilities
    clf.rewind(snapshot)
    again = clf.update(batch.select(slice(50, 120))).probabilities
    assert np.array_equal(first, again)
    with pytest.raises(ValueError, match="increase"):
        clf.update(batch.select(slice(60, 70)))  # without a rewind, time cannot go back


def test_readme_main_job_settings_keep_their_results(tmp_path):
    # The example's run section leaves lookahead at its default; forcing one step at a time
    # must reproduce its metrics exactly.
    text = (ROOT / "examples" / "search-ellipse.yaml").read_text()
    assert "lookahead_steps" not in text
    import yaml

    data = yaml.safe_load(text)
    data.setdefault("run", {})["figures"] = False
    default = _run(tmp_path, "default", data)
    data["run"]["lookahead_steps"] = 1
    stepwise = _run(tmp_path, "stepwise", data)
    _assert_same_run(default, stepwise)
    json.dumps(default[0])  # metrics stay plain JSON
