"""BioTac recordings: own .npz format round trip, CSV reading and located CSV errors."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hapticframe_biotac._frame import SIGNAL_CHANNELS, BioTacFrames, layout_for
from hapticframe_biotac._replay import (
    FORMAT_NAME,
    ReplayFormatError,
    load_csv,
    load_npz,
    load_recording,
    save_npz,
)

HEADER = (
    ["timestamp", "tdc", "tac", "pdc"]
    + [f"pac{i}" for i in range(1, 23)]
    + [f"ele{i}" for i in range(1, 20)]
)


def csv_rows(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    table = rng.integers(0, 4096, (n, len(HEADER))).astype(float)
    table[:, 0] = 100.0 + 0.01 * np.arange(n) + 0.001 * rng.random(n)  # host time with jitter
    return table


def write_csv(
    path: Path, header: list[str], table: np.ndarray, trailing_comma: bool = False
) -> Path:
    end = ",\n" if trailing_comma else "\n"
    timed = "timestamp" in header
    lines = [",".join(header) + end] + [
        ",".join(f"{v:.6f}" if j == 0 and timed else f"{v:g}" for j, v in enumerate(row)) + end
        for row in table
    ]
    path.write_text("".join(lines))
    return path


def test_csv_with_timestamps_and_a_trailing_comma(tmp_path):
    table = csv_rows(25)
    rec = load_csv(write_csv(tmp_path / "trial_bio.csv", HEADER, table, trailing_comma=True))
    frames = rec.frames
    assert rec.metadata["variant"] == "biotac" and rec.metadata["has_timestamps"]
    assert np.allclose(frames.timestamps_s, table[:, 0], atol=1e-6)
    assert np.array_equal(frames.tdc, table[:, 1]) and np.array_equal(frames.pdc, table[:, 3])
    assert np.array_equal(frames.pac, table[:, 4:26])
    assert np.array_equal(frames.electrodes, table[:, 26:45])
    assert not frames.has_ground_truth
    assert all(frames.to_sample_batch().valid[name].all() for name in SIGNAL_CHANNELS)


def test_csv_without_timestamps_is_spaced_one_frame_apart_and_keeps_ground_truth(tmp_path):
    table = csv_rows(10)[:, 1:]
    rng = np.random.default_rng(1)
    truth = np.column_stack([rng.integers(0, 2, 10), rng.random(10), rng.random(10)])
    header = HEADER[1:] + ["contact", "x_m", "y_m", "notes"]
    cells = np.column_stack([table, truth, np.zeros(10)])
    path = tmp_path / "labelled.csv"
    path.write_text(",".join(h.upper() if h.startswith("pac") else h for h in header) + "\n"
                    + "".join(",".join(repr(float(v)) for v in row) + "\n" for row in cells))
    rec = load_csv(path)
    assert np.allclose(np.diff(rec.frames.timestamps_s), 0.01)
    assert np.array_equal(rec.frames.contact, truth[:, 0])
    assert np.array_equal(rec.frames.position_m, truth[:, 1:])
    assert rec.metadata["ignored_columns"] == ["notes"]


def test_positions_without_contact_labels_load_from_csv_and_npz(tmp_path):
    """A real recording with the robot's positions and no labels feeds the sensor model."""
    table = csv_rows(8)[:, 1:]
    xy = np.random.default_rng(2).random((8, 2))
    path = tmp_path / "positions.csv"
    path.write_text(",".join(HEADER[1:] + ["x_m", "y_m"]) + "\n"
                    + "".join(",".join(repr(float(v)) for v in row) + "\n"
                              for row in np.column_stack([table, xy])))
    rec = load_csv(path)
    assert np.array_equal(rec.frames.position_m, xy) and rec.frames.contact is None
    batch = rec.frames.to_sample_batch()
    assert "position_m" in batch.channels and "contact" not in batch.channels
    back = load_npz(save_npz(tmp_path / "positions.npz", rec.frames)).frames
    assert np.array_equal(back.position_m, xy) and back.contact is None
    # Labels without positions are still refused.
    with pytest.raises(ValueError, match="contact labels need position_m"):
        BioTacFrames(rec.frames.layout, rec.frames.timestamps_s, rec.frames.pac,
                     rec.frames.pdc, rec.frames.tac, rec.frames.tdc, rec.frames.electrodes,
                     contact=np.zeros(8))


def test_csv_of_a_biotac_sp_is_recognised(tmp_path):
    layout = layout_for("biotac_sp")
    header = (
        ["pdc", "tac", "tdc"]
        + [f"pac{i}" for i in range(1, 28)]
        + [f"ele{i}" for i in range(1, 25)]
    )
    table = np.random.default_rng(2).integers(0, 4096, (5, len(header)))
    rec = load_csv(write_csv(tmp_path / "sp.csv", header, table))
    assert rec.frames.layout == layout and rec.frames.electrodes.shape == (5, 24)
    assert np.allclose(np.diff(rec.frames.timestamps_s), layout.frame_period_s)


def located(path: Path, text: str) -> ReplayFormatError:
    path.write_text(text)
    with pytest.raises(ReplayFormatError) as info:
        load_csv(path)
    return info.value


def good_text(n: int = 4) -> list[str]:
    table = csv_rows(n)
    return [",".join(HEADER)] + [
        ",".join(f"{v:g}" if j else f"{v:.4f}" for j, v in enumerate(row)) for row in table
    ]


def test_malformed_csv_errors_name_file_line_and_column(tmp_path):
    path = tmp_path / "bad.csv"
    lines = good_text()
    cells = lines[3].split(",")
    cells[7] = "abc"  # pac4, column 8
    err = located(path, "\n".join(lines[:3] + [",".join(cells)] + lines[4:]) + "\n")
    assert (err.line, err.column) == (4, 8) and "pac4" in str(err) and "'abc'" in str(err)
    assert str(err).startswith(f"{path}:4:8:")

    cells = lines[2].split(",")
    cells[30] = ""
    err = located(path, "\n".join(lines[:2] + [",".join(cells)] + lines[3:]))
    assert (err.line, err.column) == (3, 31) and "ele5" in str(err)

    err = located(path, "\n".join(lines[:2] + [lines[2] + ",7"] + lines[3:]))
    assert err.line == 3 and err.column == len(HEADER) + 1

    err = located(path, "\n".join(lines[:2] + [lines[2].rsplit(",", 3)[0]] + lines[3:]))
    assert err.line == 3 and err.column == len(HEADER) - 2

    cells = lines[4].split(",")
    cells[0] = lines[3].split(",")[0]  # repeated timestamp
    err = located(path, "\n".join(lines[:4] + [",".join(cells)]))
    assert (err.line, err.column) == (5, 1) and "does not increase" in str(err)

    cells = lines[1].split(",")
    cells[2] = "nan"
    err = located(path, "\n".join([lines[0], ",".join(cells)] + lines[2:]))
    assert (err.line, err.column) == (2, 3) and "not finite" in str(err)


def test_malformed_csv_headers_are_located(tmp_path):
    path = tmp_path / "bad.csv"
    lines = good_text()
    err = located(path, "\n".join([lines[0].replace(",ele7,", ",ele77,")] + lines[1:]))
    assert err.line == 1 and "ele7" in str(err)
    err = located(path, "\n".join([lines[0].replace("tac,", "tac,,", 1)] + lines[1:]))
    assert (err.line, err.column) == (1, 4) and "empty column name" in str(err)
    err = located(path, "\n".join([lines[0].replace("tdc", "pdc")] + lines[1:]))
    assert "twice" in str(err) and err.column == 4
    err = located(path, "\n\n" + lines[0] + ",contact\n")
    assert err.line == 3 and "x_m and y_m together" in str(err)
    err = located(path, "\n\n" + lines[0] + ",x_m\n")
    assert err.line == 3 and "x_m and y_m together" in str(err)
    err = located(path, lines[0] + "\n")
    assert "no data rows" in str(err)
    err = located(path, "")
    assert "empty" in str(err)
    with pytest.raises(ReplayFormatError, match="no such file"):
        load_csv(tmp_path / "missing.csv")


def frames_with_everything(n: int = 30) -> BioTacFrames:
    layout = layout_for("biotac")
    rng = np.random.default_rng(9)
    valid_pac = rng.random((n, 22)) > 0.05
    return BioTacFrames(
        layout,
        np.cumsum(rng.uniform(0.009, 0.011, n)),
        rng.integers(0, 4096, (n, 22)),
        rng.integers(0, 4096, n),
        rng.integers(0, 4096, n),
        rng.integers(0, 4096, n),
        rng.integers(0, 4096, (n, 19)),
        word_valid={"pac": valid_pac, "pdc": rng.random(n) > 0.1},
        frame_index=np.arange(n) * 2,
        position_m=rng.random((n, 2)),
        contact=rng.integers(0, 2, n),
    )


def test_own_format_round_trips_everything(tmp_path):
    frames = frames_with_everything()
    path = save_npz(tmp_path / "rec" / "trial.npz", frames, {"medium": "bbs", "seed": 4})
    rec = load_npz(path)
    back = rec.frames
    assert rec.metadata["medium"] == "bbs" and rec.metadata["format"] == FORMAT_NAME
    assert rec.metadata["n_frames"] == 30
    for name in (*SIGNAL_CHANNELS, "timestamps_s", "frame_index", "position_m", "contact"):
        assert np.array_equal(getattr(back, name), getattr(frames, name)), name
    assert set(back.word_valid) == {"pac", "pdc"}
    assert np.array_equal(back.word_valid["pac"], frames.word_valid["pac"])
    back_valid, valid = back.to_sample_batch().valid, frames.to_sample_batch().valid
    assert np.array_equal(back_valid["pac"], valid["pac"])
    assert load_recording(path).frames.layout.variant == "biotac"
    with pytest.raises(ReplayFormatError, match="config says biotac_sp"):
        load_recording(path, "biotac_sp")


def test_own_format_refuses_pickles_and_foreign_archives(tmp_path):
    frames = frames_with_everything(5)
    path = save_npz(tmp_path / "a.npz", frames)
    arrays = dict(np.load(path, allow_pickle=False))
    arrays["pac"] = np.array([object()] * 5, dtype=object)
    np.savez(tmp_path / "pickled.npz", **arrays)
    with pytest.raises(ReplayFormatError, match=r"pickled\.npz"):
        load_npz(tmp_path / "pickled.npz")
    np.savez(tmp_path / "foreign.npz", x=np.zeros(3))
    with pytest.raises(ReplayFormatError, match="metadata"):
        load_npz(tmp_path / "foreign.npz")
    arrays = dict(np.load(path, allow_pickle=False))
    meta = json.loads(str(arrays["metadata"]))
    arrays["metadata"] = np.array(json.dumps({**meta, "version": 99}))
    np.savez(tmp_path / "future.npz", **arrays)
    with pytest.raises(ReplayFormatError, match="version 99"):
        load_npz(tmp_path / "future.npz")
    arrays["metadata"] = np.array(json.dumps(meta))
    arrays["pdc"] = arrays["pdc"][:3]
    np.savez(tmp_path / "short.npz", **arrays)
    with pytest.raises(ReplayFormatError, match="pdc"):
        load_npz(tmp_path / "short.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ReplayFormatError, match=r"junk\.npz"):
        load_npz(tmp_path / "junk.npz")
    with pytest.raises(ValueError, match=r"\.npz"):
        save_npz(tmp_path / "x.csv", frames)
    assert zipfile.is_zipfile(path)
