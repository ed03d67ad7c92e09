"""The BioTac sensor component: conformance kit, sources, validity, determinism, config errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydantic import ValidationError

import hapticframe
from hapticframe.kinds import concatenate_batches
from hapticframe.testing import make_component, run_checks
from hapticframe_biotac import BioTacSensorConfig
from hapticframe_biotac._frame import SIGNAL_CHANNELS, BioTacFrames
from hapticframe_biotac._replay import save_npz
from hapticframe_biotac.plugin import SPECS

SPEC = SPECS[0]


@pytest.fixture(scope="module")
def registry():
    return hapticframe.make_plugin_manager(modules=["hapticframe_biotac.plugin"]).registry


def build(registry, seed: int = 0, **config):
    return make_component(SPEC, registry=registry, seed=seed, config=config)


def assert_all_pass(spec, registry):
    results = run_checks(spec, registry=registry)
    failed = [f"{r.check}: {r.message}" for r in results if r.status != "PASS"]
    assert not failed, "\n".join(failed)
    assert len(results) >= 6


def test_conformance_kit_passes_for_the_sp_and_for_a_replay(registry, tmp_path):
    # The check config (the emulated SPI stream) runs in tests/test_bundled_conformance.py.
    assert registry.plugins[hapticframe.Kind.SENSOR]["biotac"].spec == SPEC
    sp = dataclasses.replace(SPEC, check_config={**SPEC.check_config, "variant": "biotac_sp"})
    assert_all_pass(sp, registry)
    path = save_npz(tmp_path / "rec.npz", resting_frames(200))
    replay = dataclasses.replace(
        SPEC, check_config={"source": "replay", "path": str(path), "frames_per_read": 3}
    )
    assert_all_pass(replay, registry)


def resting_frames(n: int) -> BioTacFrames:
    from hapticframe_biotac._emulator import EmulatedBioTac
    from hapticframe_biotac._wire import WordStreamDecoder

    emulator = EmulatedBioTac("biotac", np.random.default_rng(5), max_frames=n)
    return WordStreamDecoder().feed(emulator.read_words(44 * n), emulator.transfer_end_time_s)


def test_spi_source_layout_validity_and_counters(registry):
    sensor = build(registry, source="spi", emulator_frames=400, frames_per_read=4,
                   parity_error_rate=0.003, stale_word_rate=0.002, dropped_frame_rate=0.03)
    channels = sensor.channels
    assert channels["pac"].shape == (22,) and channels["electrodes"].shape == (19,)
    assert channels["pdc"].unit == "count" and channels["pac"].rate_hz == pytest.approx(100.0)
    assert "contact" not in channels
    batches = []
    while not sensor.exhausted:
        batches.append(sensor.read())
    batch = concatenate_batches(batches)
    assert len(batch) == 400  # dropped frames delivered as invalid rows ("mark")
    assert np.allclose(np.diff(batch.timestamps_s), 0.01, atol=0.0011)
    stats = sensor.decoder_stats
    assert stats.dropped_frames > 0 and stats.parity_errors > 0 and stats.stale_words > 0
    invalid_rows = ~np.logical_and.reduce([batch.valid[name] for name in SIGNAL_CHANNELS])
    assert invalid_rows.sum() >= stats.dropped_frames
    assert batch.valid["pac"].mean() > 0.5  # one bad word spoils its own channel's row only
    counts = np.concatenate(
        [batch.channels[name].reshape(len(batch), -1) for name in SIGNAL_CHANNELS], axis=1
    )
    assert np.isfinite(counts).all() and counts.min() >= 0 and counts.max() <= 4095
    assert sensor.read_all().timestamps_s.size == 0


def test_spi_source_skip_mode_and_frames_per_read(registry):
    sensor = build(registry, source="spi", emulator_frames=100, frames_per_read=5,
                   dropped_frame_rate=0.1, on_dropped_frame="skip")
    batch = sensor.read_all()
    assert len(batch) == 100 - sensor.decoder_stats.dropped_frames < 100
    assert all(batch.valid[name].all() for name in SIGNAL_CHANNELS)
    first = build(registry, source="spi", emulator_frames=20, frames_per_read=5).read()
    assert len(first) == 5


def test_sp_variant_shapes(registry):
    sensor = build(registry, source="spi", variant="biotac_sp", emulator_frames=10)
    batch = sensor.read_all()
    assert batch.channels["pac"].shape == (10, 27)
    assert batch.channels["electrodes"].shape == (10, 24)
    assert sensor.channels["pac"].rate_hz == pytest.approx(4400 / 54)


def test_determinism_same_seed_same_stream_other_seed_other_stream(registry):
    config = dict(source="spi", emulator_frames=60, frames_per_read=3, parity_error_rate=0.01,
                  dropped_frame_rate=0.05, stale_word_rate=0.005)
    a = build(registry, seed=3, **config).read_all()
    b = build(registry, seed=3, **config).read_all()
    c = build(registry, seed=4, **config).read_all()
    for name in SIGNAL_CHANNELS:
        assert np.array_equal(a.channels[name], b.channels[name])
        assert np.array_equal(a.valid[name], b.valid[name])
    assert np.array_equal(a.timestamps_s, b.timestamps_s)
    assert not np.array_equal(a.channels["electrodes"], c.channels["electrodes"])


def test_replay_source_streams_the_recording_exactly(registry, tmp_path):
    frames = resting_frames(23)
    frames = BioTacFrames(
        frames.layout, frames.timestamps_s, frames.pac, frames.pdc, frames.tac, frames.tdc,
        frames.electrodes, word_valid={"tdc": np.arange(23) % 4 != 0},
        position_m=np.random.default_rng(0).random((23, 2)), contact=np.arange(23) > 10,
    )
    path = save_npz(tmp_path / "r.npz", frames)
    sensor = build(registry, source="replay", path=str(path), frames_per_read=5)
    assert set(sensor.channels) == {*SIGNAL_CHANNELS, "position_m", "contact"}
    sizes = []
    batches = []
    while not sensor.exhausted:
        batches.append(sensor.read())
        sizes.append(len(batches[-1]))
    assert sizes == [5, 5, 5, 5, 3]
    batch = concatenate_batches(batches)
    assert np.array_equal(batch.channels["electrodes"], frames.electrodes)
    assert np.array_equal(batch.channels["contact"], frames.contact)
    assert np.array_equal(batch.valid["tdc"], np.arange(23) % 4 != 0)
    assert batch.valid["pac"].all()


def test_replay_of_a_csv_through_the_sensor(registry, tmp_path):
    header = (
        ["pdc", "tac", "tdc"]
        + [f"pac{i}" for i in range(1, 23)]
        + [f"ele{i}" for i in range(1, 20)]
    )
    rows = np.random.default_rng(1).integers(0, 4096, (7, len(header)))
    path = tmp_path / "t.csv"
    path.write_text(",".join(header) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    batch = build(registry, source="replay", path=str(path)).read_all()
    assert np.array_equal(batch.channels["pdc"], rows[:, 0]) and len(batch) == 7


def test_config_errors_are_clear():
    with pytest.raises(ValidationError, match="needs a path"):
        BioTacSensorConfig(source="replay")
    with pytest.raises(ValidationError, match=r"\.npz, \.csv or \.h5"):
        BioTacSensorConfig(source="replay", path="x.txt")
    with pytest.raises(ValidationError, match="19-electrode"):
        BioTacSensorConfig(source="synthetic", variant="biotac_sp")
    with pytest.raises(ValidationError, match="never by import path"):
        BioTacSensorConfig(source="spi", spi_backend="my_lab.cheetah:Backend")
    with pytest.raises(ValidationError):
        BioTacSensorConfig(frames_per_read=0)


def _registered(monkeypatch, **targets: str) -> None:
    """Pretend installed packages register these SPI backends (name -> "module:attr")."""
    import importlib.metadata

    from hapticframe_biotac import _backends

    entries = [
        importlib.metadata.EntryPoint(name, value, _backends.ENTRY_POINT_GROUP)
        for name, value in targets.items()
    ]
    monkeypatch.setattr(_backends, "_entry_points", lambda: entries)


def test_an_spi_backend_is_chosen_by_its_registered_name(registry, monkeypatch):
    _registered(
        monkeypatch,
        cheetah="hapticframe_biotac._emulator:EmulatedBioTac",
        broken="no_such_module_here:Backend",
        wrong="hapticframe_biotac._frame:layout_for",
    )
    sensor = build(registry, source="spi", spi_backend="cheetah")
    batch = sensor.read()
    assert len(batch) == 1 and batch.valid["pac"].all()
    unknown = r"no SPI backend named 'aardvark'.*known: broken, cheetah, emulator, wrong"
    with pytest.raises(ValueError, match=unknown):
        build(registry, source="spi", spi_backend="aardvark")
    with pytest.raises(ValueError, match="'broken' cannot be loaded: ModuleNotFoundError"):
        build(registry, source="spi", spi_backend="broken")
    with pytest.raises(TypeError, match="not an SpiBatchBackend"):
        build(registry, source="spi", spi_backend="wrong")


def test_a_backend_name_registered_twice_is_refused(registry, monkeypatch):
    import importlib.metadata

    from hapticframe_biotac import _backends

    twice = [
        importlib.metadata.EntryPoint("cheetah", "a.b:C", _backends.ENTRY_POINT_GROUP),
        importlib.metadata.EntryPoint("cheetah", "d.e:F", _backends.ENTRY_POINT_GROUP),
    ]
    monkeypatch.setattr(_backends, "_entry_points", lambda: twice)
    with pytest.raises(ValueError, match="registered more than once"):
        build(registry, source="spi", spi_backend="cheetah")


def test_synthetic_source_streams_trials_with_ground_truth(registry):
    pytest.importorskip(
        "hapticframe_biotac._synthetic", reason="the synthetic generator is not written yet"
    )
    sensor = build(registry, seed=2, source="synthetic", n_trials=2, frames_per_read=50,
                   medium="bbs", has_object=True)
    assert {"position_m", "contact"} <= set(sensor.channels)
    batch = sensor.read_all()
    assert sensor.exhausted and len(batch) > 100
    assert (np.diff(batch.timestamps_s) > 0).all()
    assert set(np.unique(batch.channels["contact"])) <= {0.0, 1.0}
    assert batch.channels["pac"].shape[1:] == (22,)
    assert batch.channels["electrodes"].shape[1:] == (19,)
    again = build(registry, seed=2, source="synthetic", n_trials=2, frames_per_read=50,
                  medium="bbs", has_object=True).read_all()
    assert np.array_equal(batch.channels["pdc"], again.channels["pdc"])
    synthetic_kit = dataclasses.replace(
        SPEC, check_config={"source": "synthetic", "n_trials": 1, "frames_per_read": 10}
    )
    assert_all_pass(synthetic_kit, registry)
