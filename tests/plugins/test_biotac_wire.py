"""BioTac wire format: schedule, parity, decoder/encoder round trip, faults never shift channels."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hapticframe_biotac._emulator import EmulatedBioTac, FaultPlan, plan_from_positions
from hapticframe_biotac._frame import SIGNAL_CHANNELS, BioTacFrames, layout_for
from hapticframe_biotac._wire import (
    WordStreamDecoder,
    command_byte,
    decode_words,
    encode_frames,
    encode_values,
    has_odd_parity,
    schedule_for,
)


def random_frames(variant: str, n: int, seed: int = 0, period: float | None = None) -> BioTacFrames:
    layout = layout_for(variant)
    rng = np.random.default_rng(seed)
    dt = period or layout.frame_period_s
    return BioTacFrames(
        layout,
        dt * (1 + np.arange(n)),
        rng.integers(0, 4096, (n, layout.n_pac)),
        rng.integers(0, 4096, n),
        rng.integers(0, 4096, n),
        rng.integers(0, 4096, n),
        rng.integers(0, 4096, (n, layout.n_electrodes)),
    )


def decode_all(
    emulator: EmulatedBioTac, words_per_read: int, **decoder_kw
) -> tuple[BioTacFrames, WordStreamDecoder]:
    decoder = WordStreamDecoder(emulator.variant, **decoder_kw)
    parts = []
    while not emulator.exhausted:
        data = emulator.read_words(words_per_read)
        parts.append(decoder.feed(data, emulator.transfer_end_time_s))
    return BioTacFrames.concatenate(parts), decoder


# --- schedule and word coding ----------------------------------------------------------------


def test_command_bytes_match_the_reference_header():
    # Constants of the SynTouch driver header (hardware notes §5.2).
    assert command_byte(0) == 0x80 and command_byte(1) == 0x83
    assert command_byte(2) == 0x85 and command_byte(3) == 0x86
    slow_commands = [command_byte(16 + k) for k in (1, 2, 3, 19, 20, 24)]
    assert slow_commands == [0xA2, 0xA4, 0xA7, 0xC7, 0xC8, 0xD0]
    assert has_odd_parity(np.frombuffer(schedule_for("biotac_sp").commands, dtype=np.uint8)).all()
    with pytest.raises(ValueError):
        command_byte(64)


@pytest.mark.parametrize(
    ("variant", "words", "pac", "ele"), [("biotac", 44, 22, 19), ("biotac_sp", 54, 27, 24)]
)
def test_schedule_interleaves_pac_after_every_slow_channel(variant, words, pac, ele):
    schedule = schedule_for(variant)
    assert schedule.frame_words == words
    assert (schedule.channel[1::2] == 0).all()  # every odd slot is pac
    assert list(schedule.element[1::2]) == list(range(pac))
    slow = schedule.commands[0::2]
    assert slow[:ele] == bytes(command_byte(17 + k) for k in range(ele))
    assert slow[ele:] == bytes([0x83, 0x85, 0x86])  # PDC, TAC, TDC close the frame
    assert layout_for(variant).frame_words == words


def test_word_coding_known_answers_and_all_values_round_trip():
    # 0xFFF: 7 ones in byte 0 (odd, parity 0), 5 ones + 0 in byte 1 (odd, parity 0).
    assert encode_values([4095]).tolist() == [0xFE, 0xF8]
    # 0: both data parts empty, so both parity bits are set.
    assert encode_values([0]).tolist() == [0x01, 0x01]
    everything = np.arange(4096)
    values, ok, err = decode_words(encode_values(everything).tobytes())
    assert np.array_equal(values, everything) and ok.all() and not err.any()


def test_encoder_rejects_values_that_are_not_12_bit_counts():
    for bad in ([4096], [-1], [1.5], [np.nan]):
        with pytest.raises(ValueError):
            encode_values(bad)
    with pytest.raises(ValueError, match="whole 16-bit words"):
        decode_words(b"\x01\x01\x01")


@pytest.mark.parametrize("variant", ["biotac", "biotac_sp"])
def test_decoder_round_trips_encoder_output_exactly(variant):
    frames = random_frames(variant, 50, seed=3)
    stream = encode_frames(frames)
    assert len(stream) == 50 * 2 * layout_for(variant).frame_words
    t_end = float(frames.timestamps_s[-1])
    decoded = WordStreamDecoder(variant).feed(stream, t_end)
    for name in SIGNAL_CHANNELS:
        assert np.array_equal(getattr(decoded, name), getattr(frames, name)), name
        assert decoded.word_valid[name].all()
    assert np.allclose(decoded.timestamps_s, frames.timestamps_s, atol=1e-12)
    assert decoded.frame_index.tolist() == list(range(50))


@settings(max_examples=40, deadline=None)
@given(cuts=st.lists(st.integers(0, 20 * 88), max_size=12))
def test_decoder_is_incremental_over_arbitrary_byte_splits(cuts):
    frames = random_frames("biotac", 20, seed=5)
    stream = encode_frames(frames)
    bounds = sorted({0, len(stream), *cuts})
    decoder = WordStreamDecoder("biotac")
    slot_s = 1 / 4400
    parts = [decoder.feed(stream[a:b], (b // 2) * slot_s) for a, b in itertools.pairwise(bounds)]
    decoded = BioTacFrames.concatenate(parts)
    assert np.array_equal(decoded.pac, frames.pac)
    assert np.array_equal(decoded.electrodes, frames.electrodes)
    # each frame's time is the moment its last word arrived, whatever the transfer sizes
    assert np.allclose(decoded.timestamps_s, frames.timestamps_s, atol=1e-9)
    assert decoder.stats.dropped_frames == 0


# --- faults -------------------------------------------------------------------------------------


def expected_masks(variant: str, n: int, bad: set[tuple[int, int]]) -> dict[str, np.ndarray]:
    schedule = schedule_for(variant)
    layout = schedule.layout
    masks = {name: np.ones((n, *layout.shape_of(name)), dtype=bool) for name in SIGNAL_CHANNELS}
    for frame, slot in bad:
        name = SIGNAL_CHANNELS[schedule.channel[slot]]
        if masks[name].ndim == 2:
            masks[name][frame, schedule.element[slot]] = False
        else:
            masks[name][frame] = False
    return masks


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    variant=st.sampled_from(["biotac", "biotac_sp"]),
    errors=st.sets(
        st.tuples(st.integers(0, 5), st.integers(0, 53), st.integers(0, 1)), max_size=25
    ),
    words_per_read=st.sampled_from([1, 7, 44, 54, 100]),
)
def test_parity_errors_never_shift_other_channels(variant, errors, words_per_read):
    F = layout_for(variant).frame_words
    errors = {(f, s % F, b) for f, s, b in errors}
    frames = random_frames(variant, 6, seed=11)
    emulator = EmulatedBioTac(variant, np.random.default_rng(1), content=frames,
                              faults=plan_from_positions(parity=errors))
    decoded, decoder = decode_all(emulator, words_per_read)
    bad = {(f, s) for f, s, _ in errors}
    assert len(decoded) == 6
    assert {(f.frame, f.slot) for f in emulator.faults_of("parity")} == bad
    # a corrupted first byte can happen to read 0xA5 and pass for a sensor error word
    stats = decoder.stats
    assert stats.parity_errors + stats.sensor_errors + stats.stale_words == len(bad)
    masks = expected_masks(variant, 6, bad)
    batch = decoded.to_sample_batch()
    for name in SIGNAL_CHANNELS:
        assert np.array_equal(decoded.word_valid[name], masks[name]), name
        good = masks[name]
        # every word that arrived intact holds exactly what was sent, in its own place
        assert np.array_equal(getattr(decoded, name)[good], getattr(frames, name)[good]), name
        assert np.array_equal(batch.valid[name], good.reshape(6, -1).all(axis=1))
        assert np.isfinite(getattr(decoded, name)).all()


def test_invalid_words_hold_the_previous_valid_sample():
    frames = random_frames("biotac", 3, seed=2)
    schedule = schedule_for("biotac")
    pac_slots = schedule.slots_of("pac")
    e5 = schedule.slots_of("electrodes")[4]
    plan = plan_from_positions(
        parity=[(1, int(pac_slots[0]), 0), (1, int(pac_slots[1]), 1), (2, int(e5), 0)]
    )
    emulator = EmulatedBioTac("biotac", np.random.default_rng(0), content=frames, faults=plan)
    decoded, _ = decode_all(emulator, 44)
    # pac is one signal: samples 0 and 1 of frame 1 hold the last pac sample of frame 0
    assert decoded.pac[1, 0] == decoded.pac[1, 1] == frames.pac[0, -1]
    assert decoded.electrodes[2, 4] == frames.electrodes[1, 4]
    assert not decoded.word_valid["pac"][1, :2].any() and decoded.word_valid["pac"][1, 2:].all()


def test_stale_words_are_flagged_counted_and_held():
    frames = random_frames("biotac", 4, seed=8)
    pdc_slot = int(schedule_for("biotac").slots_of("pdc")[0])
    plan = plan_from_positions(stale=[(2, pdc_slot), (3, 0)])
    emulator = EmulatedBioTac("biotac", np.random.default_rng(0), content=frames, faults=plan)
    decoded, decoder = decode_all(emulator, 44)
    assert decoder.stats.stale_words == 2 and decoder.stats.parity_errors == 0
    assert decoded.pdc[2] == frames.pdc[1]  # held, not the error word's bits
    assert not decoded.word_valid["pdc"][2] and decoded.word_valid["pdc"][[0, 1, 3]].all()
    assert not decoded.word_valid["electrodes"][3, 0]
    assert np.array_equal(decoded.pac, frames.pac)


def test_other_sensor_error_words_are_counted_separately():
    frames = random_frames("biotac", 1)
    stream = bytearray(encode_frames(frames))
    stream[10:12] = b"\xA5\x3F"  # "E?" unknown command in slot 5
    decoder = WordStreamDecoder("biotac")
    decoded = decoder.feed(bytes(stream), 0.01)
    assert decoder.stats.sensor_errors == 1 and decoder.stats.stale_words == 0
    assert not decoded.word_valid["pac"][0, 2] and decoded.word_valid["pac"][0].sum() == 21


def test_an_absent_sensor_gives_invalid_frames_not_garbage():
    decoder = WordStreamDecoder("biotac")
    decoded = decoder.feed(b"\xff" * 88 * 3, 0.03)  # 0xFF has even parity
    assert len(decoded) == 3
    assert not any(decoded.word_valid[name].any() for name in SIGNAL_CHANNELS)
    assert (decoded.pac == 0).all() and decoder.stats.parity_errors == 132


@pytest.mark.parametrize("words_per_read", [44, 88])
def test_dropped_frames_are_marked_with_the_right_frame_numbers(words_per_read):
    frames = random_frames("biotac", 12, seed=4)
    drops = {3, 4, 9}
    emulator = EmulatedBioTac("biotac", np.random.default_rng(0), content=frames,
                              faults=plan_from_positions(dropped=drops), jitter_s=0.002)
    decoded, decoder = decode_all(emulator, words_per_read)
    assert decoder.stats.dropped_frames == 3
    assert decoded.frame_index.tolist() == list(range(12))
    lost = np.isin(np.arange(12), sorted(drops))
    kept = ~lost
    for name in SIGNAL_CHANNELS:
        rows_valid = decoded.to_sample_batch().valid[name]
        if words_per_read == 44:  # one frame per transfer: gaps land exactly where they were
            assert np.array_equal(rows_valid, kept), name
            assert np.array_equal(getattr(decoded, name)[kept], getattr(frames, name)[kept])
        else:
            assert rows_valid.sum() == kept.sum()
    assert (np.diff(decoded.timestamps_s) > 0).all()


def test_dropped_frames_can_be_skipped():
    frames = random_frames("biotac", 10, seed=4)
    emulator = EmulatedBioTac("biotac", np.random.default_rng(0), content=frames,
                              faults=plan_from_positions(dropped={2, 7}))
    decoded, decoder = decode_all(emulator, 44, on_dropped="skip")
    assert len(decoded) == 8 and decoder.stats.dropped_frames == 2
    assert decoded.frame_index.tolist() == [0, 1, 3, 4, 5, 6, 8, 9]
    assert np.array_equal(decoded.electrodes, frames.electrodes[decoded.frame_index])
    assert all(decoded.word_valid[name].all() for name in SIGNAL_CHANNELS)


def test_a_long_gap_fills_at_most_max_fill_frames():
    frames = random_frames("biotac", 2)
    stream = encode_frames(frames)
    decoder = WordStreamDecoder("biotac", max_fill_frames=5)
    decoder.feed(stream[:88], 0.01)
    out = decoder.feed(stream[88:], 0.01 + 60.0)  # an hour-like outage, scaled down
    assert decoder.stats.dropped_frames == 5999 and len(out) == 6
    assert out.frame_index[-1] == 6000


def test_random_fault_rates_are_reproducible_and_counted():
    def run(seed: int) -> tuple[BioTacFrames, WordStreamDecoder, EmulatedBioTac]:
        plan = FaultPlan(parity_error_rate=0.01, stale_word_rate=0.005, dropped_frame_rate=0.05)
        emulator = EmulatedBioTac(
            "biotac", np.random.default_rng(seed), max_frames=300, faults=plan, jitter_s=0.001
        )
        decoded, decoder = decode_all(emulator, 44)
        return decoded, decoder, emulator

    a, dec_a, emu_a = run(7)
    b, _, _ = run(7)
    c, _, _ = run(8)
    assert np.array_equal(a.pac, b.pac) and np.array_equal(a.timestamps_s, b.timestamps_s)
    assert not np.array_equal(a.pac[:10], c.pac[:10])
    assert dec_a.stats.dropped_frames == len(emu_a.faults_of("dropped")) > 0
    assert dec_a.stats.stale_words == len(emu_a.faults_of("stale")) > 0
    assert dec_a.stats.parity_errors == len(emu_a.faults_of("parity")) > 0
    assert len(a) == 300 and a.frame_index.tolist() == list(range(300))


def test_emulator_rejects_bad_settings():
    with pytest.raises(ValueError):
        FaultPlan(parity_error_rate=1.5)
    with pytest.raises(ValueError):
        EmulatedBioTac("biotac", jitter_s=0.006)
    with pytest.raises(ValueError):
        EmulatedBioTac("biotac_sp", content=random_frames("biotac", 2))
    with pytest.raises(ValueError):
        layout_for("biotac_xl")
