"""Inputs on different clocks: resampled onto the first input's timestamps by sample-and-hold
or linear interpolation, stale samples invalid, the same in a stream of ticks as on whole
recordings; and a two-input extractor through a run, training and the conformance kit."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe._errors import RunError
from hapticframe.cli._cli import main
from hapticframe.kinds import BuildContext, Component, InputAlignment, SampleBatch
from hapticframe.run._streams import InputAligner, merge_batches
from hapticframe.testing import run_checks
from tests.support import lab_devices

SUPPORT = Path(__file__).resolve().parent.parent / "support"


def primary(times) -> SampleBatch:
    t = np.asarray(times, dtype=np.float64)
    return SampleBatch(t, {"force_n": np.column_stack([t, -t])})


def secondary(times, values, valid=None) -> SampleBatch:
    v = np.asarray(values, dtype=np.float64)
    extra = {} if valid is None else {"accel": np.asarray(valid)}
    return SampleBatch(np.asarray(times, dtype=np.float64),
                       {"accel": np.column_stack([v, 2 * v])}, extra)


def test_the_default_alignment_is_exact_and_bad_alignments_are_refused():
    component = lab_devices.LinePlanner(lab_devices.LinePlannerConfig(),
                                        BuildContext(id="p", rng=np.random.default_rng(0)))
    assert isinstance(component, Component)
    assert component.input_alignment == InputAlignment() == InputAlignment("exact")
    assert InputAlignment().max_age_s == np.inf
    with pytest.raises(ValueError, match="'exact', 'hold' or 'linear'"):
        InputAlignment("nearest")  # type: ignore[arg-type]
    for age in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="max_age_s must be positive"):
            InputAlignment("hold", age)


def test_exact_alignment_still_requires_shared_timestamps():
    with pytest.raises(RunError, match=r"different times.*input_alignment"):
        merge_batches([primary([0.1, 0.2]), secondary([0.1, 0.25], [1, 2])], "c")
    joined = merge_batches([primary([0.1, 0.2]), secondary([0.1, 0.2], [1, 2])], "c")
    np.testing.assert_array_equal(joined.channels["accel"][:, 0], [1, 2])


def test_hold_takes_the_latest_sample_at_or_before_each_time():
    joined = merge_batches(
        [primary([0.10, 0.20, 0.30, 0.40]), secondary([0.05, 0.20, 0.31], [1.0, 2.0, 3.0])],
        "c", InputAlignment("hold"),
    )
    np.testing.assert_array_equal(joined.timestamps_s, [0.10, 0.20, 0.30, 0.40])
    np.testing.assert_array_equal(joined.channels["accel"], [[1, 2], [2, 4], [2, 4], [3, 6]])
    np.testing.assert_array_equal(joined.valid["accel"], [True] * 4)
    np.testing.assert_array_equal(joined.channels["force_n"][:, 0], joined.timestamps_s)


def test_linear_interpolates_between_the_neighbouring_samples():
    joined = merge_batches(
        [primary([0.10, 0.20, 0.25, 0.40]), secondary([0.0, 0.20, 0.30, 0.50], [0, 2, 3, 5])],
        "c", InputAlignment("linear"),
    )
    # 0.40 lies between 0.30 and 0.50; 0.20 is a sample (taken as it is).
    np.testing.assert_allclose(joined.channels["accel"][:, 0], [1.0, 2.0, 2.5, 4.0], rtol=1e-12)
    np.testing.assert_allclose(joined.channels["accel"][:, 1], [2.0, 4.0, 5.0, 8.0], rtol=1e-12)
    assert joined.valid["accel"].all()


def test_a_sample_older_than_max_age_is_invalid_and_nan():
    p = primary([0.10, 0.20, 0.30, 0.40, 0.50])
    s = secondary([0.09, 0.30, 0.45], [1.0, 3.0, 4.5])
    held = merge_batches([p, s], "c", InputAlignment("hold", max_age_s=0.06))
    np.testing.assert_array_equal(held.valid["accel"], [True, False, True, False, True])
    assert np.isnan(held.channels["accel"][[1, 3]]).all()
    np.testing.assert_array_equal(held.channels["accel"][[0, 2, 4], 0], [1.0, 3.0, 4.5])
    # Linear: both neighbours within max_age. 0.10 (0.09, 0.30) has its next one 0.2 s away.
    lin = merge_batches([p, s], "c", InputAlignment("linear", max_age_s=0.11))
    np.testing.assert_array_equal(lin.timestamps_s, [0.10, 0.20, 0.30, 0.40])
    np.testing.assert_array_equal(lin.valid["accel"], [False, False, True, True])
    np.testing.assert_allclose(lin.channels["accel"][3, 0], 3.0 + 1.5 * (0.1 / 0.15))
    # 0.50 follows the input's last sample and the recording ends within max_age: no later
    # sample can bracket it, so it is left out (as a stream would wait for one).


def test_times_before_the_first_sample_are_invalid():
    p = primary([0.1, 0.2, 0.3])
    for method in ("hold", "linear"):
        joined = merge_batches([p, secondary([0.15, 0.3], [1.5, 3.0])], "c",
                               InputAlignment(method))  # type: ignore[arg-type]
        np.testing.assert_array_equal(joined.valid["accel"], [False, True, True])
        assert np.isnan(joined.channels["accel"][0]).all()
        assert not any(np.isnan(joined.channels["force_n"]).ravel())
    empty = SampleBatch(np.empty(0), {"accel": np.empty((0, 2))})
    joined = merge_batches([p, empty], "c", InputAlignment("hold"))
    assert joined.channels["accel"].shape == (3, 2) and not joined.valid["accel"].any()


def test_an_invalid_source_sample_stays_invalid():
    s = secondary([0.1, 0.2, 0.3], [1.0, np.nan, 3.0], valid=[True, False, True])
    held = merge_batches([primary([0.15, 0.25, 0.35]), s], "c", InputAlignment("hold"))
    np.testing.assert_array_equal(held.valid["accel"], [True, False, True])
    lin = merge_batches([primary([0.15, 0.25, 0.3]), s], "c", InputAlignment("linear"))
    np.testing.assert_array_equal(lin.valid["accel"], [False, False, True])
    assert np.isnan(lin.channels["accel"][:2]).all()


def two_clocks(rng: np.random.Generator) -> tuple[SampleBatch, SampleBatch]:
    t1 = np.cumsum(rng.uniform(0.008, 0.012, 400))
    t2 = np.cumsum(rng.uniform(0.02, 0.05, 160)) - 0.03
    t2 = t2[t2 < t1[-1] + 0.1]
    t2 = np.delete(t2, np.arange(40, 46))  # a gap longer than max_age
    first = SampleBatch(t1, {"force_n": rng.normal(size=(len(t1), 3))})
    valid = rng.uniform(size=len(t2)) > 0.1
    values = rng.normal(size=(len(t2), 4))
    values[~valid] = np.nan
    second = SampleBatch(t2, {"accel": values}, {"accel": valid})
    return first, second


def assert_same(a: SampleBatch, b: SampleBatch) -> None:
    np.testing.assert_array_equal(a.timestamps_s, b.timestamps_s)
    assert set(a.channels) == set(b.channels) and set(a.valid) == set(b.valid)
    for name in a.channels:
        np.testing.assert_array_equal(a.channels[name], b.channels[name])  # NaN == NaN
    for name in a.valid:
        np.testing.assert_array_equal(a.valid[name], b.valid[name])


@pytest.mark.parametrize("method", ["hold", "linear"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_stream_of_ticks_gives_exactly_the_batch_result(method, seed):
    rng = np.random.default_rng(seed)
    first, second = two_clocks(rng)
    alignment = InputAlignment(method, max_age_s=0.08)  # type: ignore[arg-type]
    whole = merge_batches([first, second], "c", alignment)
    assert 0 < int(whole.valid["accel"].sum()) < len(whole)  # stale, missing and good ones
    aligner = InputAligner(alignment, "c")
    # Ticks of 0 to 120 ms: many hold no sample of one input, or of both. The second input
    # is read a little later in each tick than the first (sensors read one after the
    # other), so it delivers samples the first input's next tick still needs.
    cuts = np.cumsum(rng.uniform(0.0, 0.12, 200))
    cuts = [*cuts[cuts < first.timestamps_s[-1] + 0.2], np.inf]
    skews = rng.uniform(0.0, 0.06, len(cuts))
    parts, low, low_second, delayed = [], -np.inf, -np.inf, 0
    for high, skew in zip(cuts, skews, strict=True):
        high_second = max(high + skew, low_second)
        tick = [first.select((first.timestamps_s > low) & (first.timestamps_s <= high)),
                second.select((second.timestamps_s > low_second)
                              & (second.timestamps_s <= high_second))]
        parts.append(aligner.push(tick))
        delayed += int(np.sum(parts[-1].timestamps_s <= low))  # from an earlier tick
        low, low_second = high, high_second
    streamed = SampleBatch(
        np.concatenate([p.timestamps_s for p in parts]),
        {k: np.concatenate([p.channels[k] for p in parts]) for k in whole.channels},
        {k: np.concatenate([p.valid[k] for p in parts]) for k in whole.valid},
    )
    assert_same(streamed, whole)
    # Linear waits for the sample after a time, so some samples come a tick late; hold never.
    assert (delayed > 0) == (method == "linear")


def test_a_rewound_aligner_replays_the_same_samples():
    first, second = two_clocks(np.random.default_rng(5))
    aligner = InputAligner(InputAlignment("linear", 0.08), "c")
    aligner.push([first.select(slice(0, 50)), second.select(second.timestamps_s <= 0.5)])
    snapshot = aligner.checkpoint()
    tick = [first.select(slice(50, 90)),
            second.select((second.timestamps_s > 0.5) & (second.timestamps_s <= 0.9))]
    once = aligner.push(tick)
    aligner.rewind(snapshot)
    assert_same(aligner.push(tick), once)
    aligner.reset()
    assert len(aligner.push([first.select(slice(0, 1)), second.select(slice(0, 0))])) == 1


# --- through a run, training and the kit --------------------------------------------------

def experiment(method: str) -> str:
    return f"""\
schema_version: 1
name: two-clocks
seed: 1
sensors:
  - {{id: ft, type: lab-clock, config: {{channel: force_n, rate_hz: 100, phase_s: 0.004}}}}
  - {{id: imu, type: lab-clock, config: {{channel: accel_m_per_s2, rate_hz: 30,
                                          phase_s: 0.02}}}}
feature_extractors:
  - {{id: mix, type: lab-mix, inputs: [ft, imu], config: {{method: {method}}}}}
"""


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    shutil.copy(SUPPORT / "lab_devices.py", tmp_path / "lab_devices.py")
    monkeypatch.delitem(sys.modules, "lab_devices", raising=False)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def recordings(method: str) -> tuple[SampleBatch, SampleBatch, lab_devices.MixExtractor]:
    def build(config):  # type: ignore[no-untyped-def]
        return lab_devices.ClockSensor(config, BuildContext(id="s", rng=np.random.default_rng(0)))

    ft = build(lab_devices.ClockConfig(channel="force_n", rate_hz=100, phase_s=0.004))
    imu = build(lab_devices.ClockConfig(channel="accel_m_per_s2", rate_hz=30, phase_s=0.02))
    mix = lab_devices.MixExtractor(lab_devices.MixConfig(method=method),  # type: ignore[arg-type]
                                   BuildContext(id="mix", rng=np.random.default_rng(0)))
    return ft.read_all(), imu.read_all(), mix


@pytest.mark.parametrize("method", ["hold", "linear"])
def test_a_two_input_extractor_runs_as_it_would_on_whole_recordings(lab_dir, method):
    (lab_dir / "e.yaml").write_text(experiment(method))
    out = lab_dir / "out"
    assert main(["run", "--plugin-module", "lab_devices", "e.yaml", "--out", str(out),
                 "--quiet"]) == 0
    trace = np.load(out / "trace.npz")
    ft, imu, mix = recordings(method)
    joined = merge_batches([ft, imu], "mix", mix.input_alignment)
    expected = mix.transform(joined)
    np.testing.assert_array_equal(trace["feature_extractor/mix/timestamps_s"],
                                  expected.timestamps_s)
    np.testing.assert_array_equal(trace["feature_extractor/mix/mix"], expected.channels["mix"])
    # The IMU starts 16 ms after the force sensor: the first force samples had no partner.
    assert not joined.valid["accel_m_per_s2"][0] and joined.valid["accel_m_per_s2"][5:].all()


def test_training_joins_inputs_as_the_run_does(lab_dir):
    (lab_dir / "e.yaml").write_text(experiment("hold"))
    out = lab_dir / "trained"
    assert main(["train", "--plugin-module", "lab_devices", "e.yaml", "--out", str(out)]) == 0
    report = json.loads((out / "train.json").read_text())["reports"]["mix"]
    ft, imu, mix = recordings("hold")
    joined = merge_batches([ft, imu], "mix", mix.input_alignment)
    assert report == {"recordings": 1, "samples": len(ft),
                      "valid_accel": int(joined.valid["accel_m_per_s2"].sum())}
    assert 0 < report["valid_accel"] < report["samples"]


def test_the_kit_checks_a_two_clock_consumer_streams_as_batch():
    specs = {s.name: s for s in lab_devices.hapticframe_feature_extractors()}
    for method in ("hold", "linear"):
        spec = specs["lab-mix"]
        spec = type(spec)(**{**spec.__dict__, "check_config": {"method": method}})
        results = {r.check: r for r in run_checks(spec)}
        assert results["check_aligned_inputs_stream_as_batch"].status == "PASS", results
        assert all(r.status == "PASS" for r in results.values()), results
    # A consumer that forgets its state between updates is caught on two clocks too.
    results = {r.check: r for r in run_checks(specs["lab-mix-forgetful"])}
    failed = results["check_aligned_inputs_stream_as_batch"]
    assert failed.status == "FAIL"
    assert "inputs aligned tick by tick must equal the batch path" in failed.message


def test_an_aligner_keeps_bounded_memory_while_its_first_input_is_silent():
    from hapticframe.run._streams import MAX_KEPT_S

    aligner = InputAligner(InputAlignment("hold"), "observer")
    silent = SampleBatch(np.empty(0), {"force_n": np.empty((0, 3))})
    for k in range(3000):  # 30 s of a 100 Hz IMU while the force sensor says nothing
        t = 0.01 * (k + 1)
        imu = SampleBatch(np.array([t]), {"acceleration_m_per_s2": np.full((1, 3), t)})
        assert len(aligner.push([silent, imu])) == 0
    kept = aligner.checkpoint()[0][0]
    assert len(kept) <= MAX_KEPT_S / 0.01 + 2
    # The force sensor comes back: its samples get the IMU's latest, held.
    force = SampleBatch(np.array([30.005]), {"force_n": np.zeros((1, 3))})
    imu = SampleBatch(np.array([30.01]), {"acceleration_m_per_s2": np.full((1, 3), 30.01)})
    joined = aligner.push([force, imu])
    np.testing.assert_allclose(joined.channels["acceleration_m_per_s2"], [[30.0, 30.0, 30.0]])
