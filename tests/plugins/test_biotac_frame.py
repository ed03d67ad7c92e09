"""BioTac frame records: validation, SampleBatch conversion, extremes of the decoder's input."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe.kinds import SampleBatch
from hapticframe_biotac._frame import (
    LAYOUTS,
    SIGNAL_CHANNELS,
    BioTacFrames,
    check_counts,
    layout_for,
)
from hapticframe_biotac._wire import WordStreamDecoder, encode_frames


def frames(n: int = 4, variant: str = "biotac", **kw) -> BioTacFrames:
    layout = layout_for(variant)
    rng = np.random.default_rng(n)
    return BioTacFrames(
        layout, 0.01 * (1 + np.arange(n)), rng.integers(0, 4096, (n, layout.n_pac)),
        rng.integers(0, 4096, n), rng.integers(0, 4096, n), rng.integers(0, 4096, n),
        rng.integers(0, 4096, (n, layout.n_electrodes)), **kw,
    )


def test_layouts_follow_the_frame_schedules():
    biotac, sp = LAYOUTS["biotac"], LAYOUTS["biotac_sp"]
    assert (biotac.n_pac, biotac.n_electrodes, biotac.frame_words) == (22, 19, 44)
    assert (sp.n_pac, sp.n_electrodes, sp.frame_words) == (27, 24, 54)
    assert LAYOUTS["biotac"].frame_rate_hz == pytest.approx(100.0)
    infos = LAYOUTS["biotac"].channel_infos(ground_truth=True)
    assert infos["pac"].shape == (22,) and infos["pdc"].shape == ()
    assert infos["position_m"].unit == "m"


def test_sample_batch_round_trip_keeps_values_validity_and_ground_truth():
    valid = np.ones((4, 19), dtype=bool)
    valid[2, 5] = False
    original = frames(
        word_valid={"electrodes": valid}, position_m=np.zeros((4, 2)), contact=[0, 1, 1, 0]
    )
    batch = original.to_sample_batch()
    assert isinstance(batch, SampleBatch)
    assert set(batch.valid) == set(SIGNAL_CHANNELS)
    assert batch.valid["electrodes"].tolist() == [True, True, False, True]
    assert batch.valid["pac"].all()
    back = BioTacFrames.from_sample_batch(batch)
    for name in SIGNAL_CHANNELS:
        assert np.array_equal(getattr(back, name), getattr(original, name))
    # a row flag covers every word of its channel on the way back
    assert not back.word_valid["electrodes"][2].any()
    assert back.word_valid["electrodes"][[0, 1, 3]].all()
    assert np.array_equal(back.contact, original.contact)
    with pytest.raises(ValueError, match="lacks BioTac channel"):
        BioTacFrames.from_sample_batch(SampleBatch(np.zeros(1), {"pac": np.zeros((1, 22))}))


def test_frames_reject_malformed_input():
    layout = layout_for("biotac")
    good = frames(3)
    with pytest.raises(ValueError, match="strictly increasing"):
        BioTacFrames(
            layout, [0.0, 0.0, 1.0], good.pac, good.pdc, good.tac, good.tdc, good.electrodes
        )
    with pytest.raises(ValueError, match="finite"):
        BioTacFrames(
            layout, [0.0, np.nan, 1.0], good.pac, good.pdc, good.tac, good.tdc, good.electrodes
        )
    with pytest.raises(ValueError, match="pac"):
        BioTacFrames(
            layout, good.timestamps_s, good.pac[:, :21], good.pdc, good.tac, good.tdc,
            good.electrodes,
        )
    with pytest.raises(ValueError, match="rows"):
        BioTacFrames(
            layout, good.timestamps_s, good.pac, good.pdc[:2], good.tac, good.tdc, good.electrodes
        )
    with pytest.raises(ValueError, match="contact labels need position_m"):
        frames(3, contact=[0, 1, 0])
    with pytest.raises(ValueError, match="word_valid"):
        frames(3, word_valid={"pac": np.ones(3, dtype=bool)})
    with pytest.raises(ValueError, match="different BioTac variants"):
        BioTacFrames.concatenate([frames(2), frames(2, "biotac_sp")])
    with pytest.raises(ValueError):
        BioTacFrames.concatenate([])


def test_check_counts_accepts_only_integral_12_bit_values():
    assert check_counts([0, 4095.0], "x").tolist() == [0, 4095]
    assert check_counts(np.empty(0), "x").size == 0
    cases = (([4096], "0..4095"), ([-1], "0..4095"), ([2.5], "integer"), ([np.inf], "finite"))
    for bad, why in cases:
        with pytest.raises(ValueError, match=why):
            check_counts(bad, "x")


def test_decoder_extremes_empty_single_word_and_bad_times():
    decoder = WordStreamDecoder()
    assert len(decoder.feed(b"", 0.0)) == 0
    assert len(decoder.feed(b"\x01", 0.0)) == 0  # half a word waits for the rest
    with pytest.raises(ValueError, match="finite"):
        decoder.feed(b"\x01", float("nan"))
    decoder.reset()
    stream = encode_frames(frames(3))
    first = decoder.feed(stream[:88], 5.0)
    # the host clock stepping back must not break the strictly increasing timestamps
    later = decoder.feed(stream[88:], 4.0)
    assert len(later) == 2 and later.timestamps_s[0] > first.timestamps_s[-1]
    assert (np.diff(later.timestamps_s) > 0).all() and decoder.stats.dropped_frames == 0


def test_decoder_rejects_unknown_settings():
    with pytest.raises(ValueError):
        WordStreamDecoder(on_dropped="ignore")  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        WordStreamDecoder("biotac_xl")
