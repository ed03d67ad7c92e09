"""Streaming EMD feature tensors: ring buffers, delay, streaming equals batch, invalid data."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe.kinds import BuildContext, SampleBatch, concatenate_batches
from hapticframe_bench import synthetic_biotac_frames
from hapticframe_tactile_features._config import EMDFeaturesConfig
from hapticframe_tactile_features._emd import emd
from hapticframe_tactile_features._emd_features import EMDFeatureExtractor
from hapticframe_tactile_features._streaming import RingBuffer, hold_invalid


def _extractor(**config: object) -> EMDFeatureExtractor:
    return EMDFeatureExtractor(
        EMDFeaturesConfig(**config), BuildContext("fx", np.random.default_rng(0))
    )


def _frames(n: int, seed: int = 0) -> SampleBatch:
    return synthetic_biotac_frames(n, np.random.default_rng(seed))


def test_ring_buffer_keeps_the_newest_samples_in_order() -> None:
    rng = np.random.default_rng(1)
    ring = RingBuffer(7, (2,))
    ring.fill(np.array([-1.0, -2.0]))
    history = [np.array([-1.0, -2.0])] * 7
    for size in rng.integers(1, 12, size=40):
        values = rng.standard_normal((int(size), 2))
        ring.push(values)
        history.extend(values)
        assert np.array_equal(ring.view(), np.array(history[-7:]))
    with pytest.raises(ValueError):
        ring.view()[0, 0] = 1.0  # read-only


def test_hold_invalid_repeats_the_last_valid_value() -> None:
    values = np.array([1.0, np.nan, 3.0, np.nan, np.nan, 6.0])
    out = hold_invalid(values, np.isfinite(values), np.array(9.0))
    assert out.tolist() == [1.0, 1.0, 3.0, 3.0, 3.0, 6.0]
    first_bad = hold_invalid(np.array([np.nan, 2.0]), np.array([False, True]), np.array(9.0))
    assert first_bad.tolist() == [9.0, 2.0]


def test_output_layout_and_delay() -> None:
    fx = _extractor(delay_frames=3)
    frames = _frames(40)
    out = fx.update(frames)
    assert fx.delay_s == pytest.approx(0.03)
    assert {k: v.shape for k, v in out.channels.items()} == {
        "pac_imfs": (37, 8, 22),
        "pdc_imfs": (37, 5, 5),
        "electrodes_window": (37, 19, 5),
    }
    counts = fx.imf_counts
    assert 1 <= counts["pac"] <= 8 and 1 <= counts["pdc"] <= 5
    assert np.all(out.channels["pac_imfs"][-1, counts["pac"] :] == 0.0)
    # The features emitted after frame k describe frame k - 3.
    assert np.array_equal(out.timestamps_s, frames.timestamps_s[:-3])
    assert {k: v.shape for k, v in fx.output_channels.items()} == {
        "pac_imfs": (8, 22),
        "pdc_imfs": (5, 5),
        "electrodes_window": (19, 5),
    }


def test_tensors_are_the_emd_of_the_window_around_the_described_frame() -> None:
    delay, n = 2, 60
    fx = _extractor(delay_frames=delay)
    frames = _frames(n, seed=3)
    out = fx.update(frames)
    pac = frames.channels["pac"].ravel()
    pdc = frames.channels["pdc"]
    k = 45  # the newest frame when output row k - delay was emitted
    row = k - delay
    pac_window = pac[(k + 1) * 22 - 512 : (k + 1) * 22]
    expected_pac = emd(pac_window, 8).imfs[:, 512 - 22 * (delay + 1) : 512 - 22 * delay]
    assert np.array_equal(out.channels["pac_imfs"][row], expected_pac)
    # pdc: 64-sample window; frame 45 - 64 + 1 < 0, so the window starts with the first
    # frame's value repeated (the documented start-of-stream padding).
    pdc_window = np.concatenate((np.full(64 - (k + 1), pdc[0]), pdc[: k + 1]))
    expected_pdc = emd(pdc_window, 5).imfs[:, 64 - delay - 5 : 64 - delay]
    assert np.array_equal(out.channels["pdc_imfs"][row], expected_pdc)
    # Electrodes: the raw values of the described frame and the 4 before it.
    assert np.array_equal(
        out.channels["electrodes_window"][row], frames.channels["electrodes"][row - 4 : row + 1].T
    )


def test_start_of_stream_pads_with_the_first_frame() -> None:
    fx = _extractor(delay_frames=0)
    frames = _frames(3)
    out = fx.update(frames)
    window = out.channels["electrodes_window"][0]
    assert np.array_equal(window, np.repeat(frames.channels["electrodes"][0][:, None], 5, axis=1))


def test_numba_and_numpy_backends_give_the_same_feature_tensors() -> None:
    pytest.importorskip("numba")
    frames = _frames(80, seed=5)
    compiled = _extractor(delay_frames=2, emd_backend="numba").transform(frames)
    reference = _extractor(delay_frames=2, emd_backend="numpy").transform(frames)
    for name, array in reference.channels.items():
        scale = np.abs(array).max()
        assert np.abs(compiled.channels[name] - array).max() <= 1e-12 * scale, name


@pytest.mark.parametrize("seed", [0, 1])
def test_streaming_in_any_chunks_equals_the_batch_path(seed: int) -> None:
    fx = _extractor(delay_frames=3)
    frames = _frames(90, seed)
    whole = fx.transform(frames)
    fx.reset()
    sizes = np.random.default_rng(seed).integers(1, 9, size=90)
    parts, start = [], 0
    for size in sizes:
        if start >= 90:
            break
        parts.append(fx.update(frames.select(slice(start, start + int(size)))))
        start += int(size)
    streamed = concatenate_batches(parts)
    assert np.array_equal(streamed.timestamps_s, whole.timestamps_s)
    for name, array in whole.channels.items():
        assert np.array_equal(streamed.channels[name], array), name


def test_only_the_configured_modalities_are_read_and_computed() -> None:
    fx = _extractor(modalities=["electrodes"], delay_frames=1)
    frames = _frames(10)
    only_electrodes = SampleBatch(
        frames.timestamps_s, {"electrodes": frames.channels["electrodes"]}
    )
    out = fx.update(only_electrodes)
    assert set(out.channels) == {"electrodes_window"} and len(out) == 9
    with pytest.raises(ValueError, match="lacks channel"):
        _extractor(modalities=["pdc"]).update(only_electrodes)


def test_invalid_samples_are_held_and_flagged() -> None:
    frames = _frames(30, seed=5)
    pac = frames.channels["pac"].copy()
    pdc = frames.channels["pdc"].copy()
    pac[10, 4:9] = np.nan
    pdc[12] = np.inf
    electrodes_valid = np.ones(30, dtype=bool)
    electrodes_valid[14] = False
    corrupted = SampleBatch(
        frames.timestamps_s,
        {"pac": pac, "pdc": pdc, "electrodes": frames.channels["electrodes"]},
        {"electrodes": electrodes_valid},
    )
    out = _extractor(delay_frames=0).update(corrupted)
    for array in out.channels.values():
        assert np.isfinite(array).all()
    assert np.flatnonzero(~out.valid["pac_imfs"]).tolist() == [10]
    assert np.flatnonzero(~out.valid["pdc_imfs"]).tolist() == [12]
    assert np.flatnonzero(~out.valid["electrodes_window"]).tolist() == [14]
    # The flagged electrode frame repeats frame 13's values.
    assert np.array_equal(
        out.channels["electrodes_window"][14][:, -1], frames.channels["electrodes"][13]
    )


def test_frames_before_the_first_valid_one_are_dropped() -> None:
    frames = _frames(12)
    pdc = frames.channels["pdc"].copy()
    pdc[:3] = np.nan
    batch = SampleBatch(frames.timestamps_s, {**frames.channels, "pdc": pdc})
    out = _extractor(delay_frames=1).update(batch)
    assert np.array_equal(out.timestamps_s, frames.timestamps_s[3:-1])


def test_all_nan_input_gives_no_output_rather_than_nan() -> None:
    frames = _frames(5)
    nan = {k: np.full_like(v, np.nan) for k, v in frames.channels.items()}
    out = _extractor().update(SampleBatch(frames.timestamps_s, nan))
    assert len(out) == 0


def test_wrong_shapes_are_rejected() -> None:
    frames = _frames(4)
    bad = SampleBatch(frames.timestamps_s, {**frames.channels, "electrodes": np.zeros((4, 24))})
    with pytest.raises(ValueError, match="electrodes"):
        _extractor().update(bad)
    assert _extractor(electrode_count=24).update(bad).channels["electrodes_window"].shape[1:] == (
        24,
        5,
    )


def test_config_enforces_the_window_sizes_and_modalities() -> None:
    with pytest.raises(ValidationError):
        EMDFeaturesConfig(pac_window_samples=256)
    with pytest.raises(ValidationError):
        EMDFeaturesConfig(pdc_window_samples=32)
    with pytest.raises(ValidationError):
        EMDFeaturesConfig(modalities=["pac", "pac"])
    with pytest.raises(ValidationError):
        EMDFeaturesConfig(modalities=[])
    with pytest.raises(ValidationError):
        EMDFeaturesConfig(delay_frames=30)  # 22 * 31 pac samples exceed the 512 window
    assert EMDFeaturesConfig(modalities=["electrodes", "pac"]).modalities == ("pac", "electrodes")


def test_look_ahead_reduces_the_end_effect_on_imf1() -> None:
    # IMF1 of the described frame, against the same samples in the middle of one long
    # decomposition: without look-ahead the newest samples sit on the window's edge.
    frames = _frames(400, seed=11)
    pac = frames.channels["pac"].ravel()
    reference = emd(pac, 8).imfs[0]

    def error(delay: int) -> float:
        out = _extractor(delay_frames=delay).update(frames)
        rows = np.arange(100, 300)
        got = out.channels["pac_imfs"][rows, 0].ravel()
        want = np.concatenate([reference[r * 22 : (r + 1) * 22] for r in rows])
        return float(np.median(np.abs(got - want)) / np.median(np.abs(want)))

    no_delay, with_delay = error(0), error(3)
    assert with_delay < 0.5 * no_delay
