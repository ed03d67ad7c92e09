"""Recordings are bounded: regular files only, CSVs streamed, .npz shapes checked first.

The reproductions of issue 16 §2 (recordings), each on a small generated file.
"""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hapticframe_biotac import _replay
from hapticframe_biotac._frame import BioTacFrames, layout_for
from hapticframe_biotac._replay import ReplayFormatError, load_csv, load_npz, save_npz
from hapticframe_recording import RecordingError, load_labels, load_recording

HEADER = (
    ["timestamp", "tdc", "tac", "pdc"]
    + [f"pac{i}" for i in range(1, 23)]
    + [f"ele{i}" for i in range(1, 20)]
)


def csv_text(
    n: int, *, truth: bool = False, trailing_comma: bool = True, seed: int = 0, start: int = 0
) -> str:
    rng = np.random.default_rng(seed)
    header = HEADER + (["contact", "x_m", "y_m"] if truth else [])
    end = ",\n" if trailing_comma else "\n"
    lines = [",".join(header) + end]
    for k in range(start, start + n):
        cells = [f"{100.0 + 0.01 * k:.4f}"] + [str(v) for v in rng.integers(0, 4096, 44)]
        if truth:
            cells += [str(int(k % 7 > 3)), f"{0.001 * k:.4f}", "0.05"]
        lines.append(",".join(cells) + end)
    return "".join(lines)


def frames(n: int = 12) -> BioTacFrames:
    rng = np.random.default_rng(3)

    def counts(*shape: int) -> np.ndarray:
        return rng.integers(0, 4096, shape).astype(np.float64)

    return BioTacFrames(
        layout_for("biotac"), np.arange(1, n + 1, dtype=np.float64) * 0.01, counts(n, 22),
        counts(n), counts(n), counts(n), counts(n, 19), position_m=rng.random((n, 2)),
        contact=(np.arange(n) % 2).astype(np.float64),
    )


def resave(path: Path, **changes: np.ndarray) -> Path:
    with np.load(path, allow_pickle=False) as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays.update(changes)
    np.savez(path, **arrays)
    return path


# --- CSV streaming -----------------------------------------------------------------------------


@pytest.fixture
def small_blocks(monkeypatch):
    """Blocks of 5 lines, so a small file crosses many block boundaries."""
    monkeypatch.setattr(_replay, "_BLOCK_LINES", 5)


def test_a_csv_read_in_blocks_equals_one_read_whole(tmp_path, monkeypatch):
    path = tmp_path / "rec.csv"
    path.write_text(csv_text(23, truth=True))
    whole = load_csv(path).frames
    monkeypatch.setattr(_replay, "_BLOCK_LINES", 4)
    blocks = load_csv(path).frames
    for name in ("timestamps_s", "pac", "pdc", "tac", "tdc", "electrodes", "position_m",
                 "contact"):
        assert np.array_equal(getattr(blocks, name), getattr(whole, name)), name
    assert len(blocks) == 23 and blocks.contact.sum() == sum(k % 7 > 3 for k in range(23))
    # The same values quoted (numpy's fast parser is bypassed) read the same.
    quoted = tmp_path / "quoted.csv"
    lines = path.read_text().splitlines()
    quoted.write_text("\n".join([lines[0]] + [f'"{line.split(",")[0]}",' + line.split(",", 1)[1]
                                              for line in lines[1:]]) + "\n")
    assert np.array_equal(load_csv(quoted).frames.pac, whole.pac)


def test_faults_across_block_boundaries_are_located(tmp_path, small_blocks):
    lines = csv_text(20).splitlines()
    path = tmp_path / "bad.csv"
    # Line 11 is the first of the third block; its time repeats line 10's.
    lines[10] = lines[9].split(",")[0] + "," + lines[10].split(",", 1)[1]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReplayFormatError, match="does not increase") as info:
        load_csv(path)
    assert (info.value.line, info.value.column) == (11, 1)
    lines = csv_text(20).splitlines()
    cells = lines[13].split(",")
    cells[5] = "inf"
    path.write_text("\n".join(lines[:13] + [",".join(cells)] + lines[14:]) + "\n")
    with pytest.raises(ReplayFormatError, match=r"'pac2': 'inf' is not finite") as info:
        load_csv(path)
    assert (info.value.line, info.value.column) == (14, 6)
    assert str(info.value).startswith(f"{path}:14:6:")


@pytest.mark.parametrize("label", ["7", "-0.5"])
def test_csv_contact_labels_other_than_0_and_1_are_refused(tmp_path, small_blocks, label):
    lines = csv_text(12, truth=True).splitlines()
    cells = lines[8].split(",")
    column = HEADER.index("ele19") + 2  # contact follows the last electrode
    cells[column - 1] = label
    path = tmp_path / "labels.csv"
    path.write_text("\n".join(lines[:8] + [",".join(cells)] + lines[9:]) + "\n")
    with pytest.raises(ReplayFormatError, match=f"'contact': {label} is not a contact label"
                       ) as info:
        load_csv(path)
    assert (info.value.line, info.value.column) == (9, column)


def test_csv_positions_must_be_finite(tmp_path):
    lines = csv_text(6, truth=True).splitlines()
    cells = lines[4].split(",")
    cells[-2] = "inf"  # y_m; the last cell is the trailing comma's
    path = tmp_path / "pos.csv"
    path.write_text("\n".join(lines[:4] + [",".join(cells)] + lines[5:]) + "\n")
    with pytest.raises(ReplayFormatError, match=r"'y_m': 'inf' is not finite") as info:
        load_csv(path)
    assert info.value.line == 5 and info.value.column == len(HEADER) + 3


def test_a_csv_over_the_memory_limit_is_refused_with_the_estimate(tmp_path, small_blocks):
    path = tmp_path / "big.csv"
    path.write_text(csv_text(200))
    # 47 float64 per frame: 200 frames take 75 kB; the estimate comes after the first block.
    with pytest.raises(ReplayFormatError, match=r"about \d[\d,]* rows of 45 columns .* take "
                       r"[\d.]+ kB in memory; the limit for one recording is 10 kB") as info:
        load_csv(path, max_bytes=10_000)
    assert str(info.value).startswith(str(path))
    assert len(load_csv(path, max_bytes=100_000).frames) == 200


# --- .npz shape, archive and content checks ----------------------------------------------------


def npz_declaring(path: Path, shape: tuple[int, ...]) -> Path:
    """An archive whose 'pac' member is only a header declaring ``shape`` (no data at all)."""
    header = {"descr": "<f8", "fortran_order": False, "shape": shape}
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("pac.npy", "w") as member:
            np.lib.format.write_array_header_1_0(member, header)
    return path


def test_an_npz_declaring_a_huge_shape_is_refused_from_its_header(tmp_path):
    path = npz_declaring(tmp_path / "huge.npz", (20_000_000, 22))
    assert path.stat().st_size < 1000
    with pytest.raises(ReplayFormatError, match=r"declares arrays of 3.52 GB \('pac' 20000000 "
                       r"x 22 float64\); the limit for one recording is 2.15 GB") as info:
        load_npz(path)
    assert str(info.value).startswith(f"{path}: ")
    # A real archive, compressed small, past a lower limit.
    real = save_npz(tmp_path / "real.npz", frames(40))
    with pytest.raises(ReplayFormatError, match="the limit for one recording is 1 kB"):
        load_npz(real, max_bytes=1000)
    assert len(load_npz(real).frames) == 40


def test_a_truncated_npz_and_an_npy_named_npz_are_located(tmp_path):
    whole = save_npz(tmp_path / "whole.npz", frames())
    cut = tmp_path / "cut.npz"
    cut.write_bytes(whole.read_bytes()[: whole.stat().st_size // 2])
    with pytest.raises(ReplayFormatError, match=r"cut\.npz: the file is truncated"):
        load_npz(cut)
    npy = tmp_path / "array.npz"
    with npy.open("wb") as handle:
        np.save(handle, np.zeros((3, 22)))
    with pytest.raises(ReplayFormatError, match=r"array\.npz: the file is a single \.npy array"):
        load_npz(npy)
    for target in (cut, npy):
        with pytest.raises(RecordingError, match=str(target.name)):
            load_recording(target)


def test_a_member_cut_short_inside_the_archive_is_located(tmp_path):
    path = tmp_path / "short.npz"
    with zipfile.ZipFile(path, "w") as archive:
        with archive.open("pac.npy", "w") as member:
            np.lib.format.write_array_header_1_0(
                member, {"descr": "<f8", "fortran_order": False, "shape": (10, 22)})
            member.write(np.zeros(5 * 22).tobytes())  # half the rows it declares
    with pytest.raises(ReplayFormatError, match=r"short\.npz: array 'pac' is truncated"):
        load_npz(path)


def test_npz_ground_truth_must_be_finite_positions_and_0_1_contact(tmp_path):
    path = save_npz(tmp_path / "rec.npz", frames())
    position = frames().position_m.copy()
    position[5, 0] = np.inf
    resave(path, position_m=position)
    with pytest.raises(ReplayFormatError, match=r"rec\.npz: 'position_m' row 5 \(x\) is inf"):
        load_npz(path)
    for label in (7.0, -0.5):
        path = save_npz(tmp_path / "rec.npz", frames())
        contact = frames().contact.copy()
        contact[3] = label
        resave(path, contact=contact)
        with pytest.raises(ReplayFormatError,
                           match=rf"'contact' row 3 is {label:g}; contact labels are 0"):
            load_npz(path)


def test_complex_and_non_finite_channels_are_refused_naming_the_row(tmp_path):
    path = save_npz(tmp_path / "rec.npz", frames())
    resave(path, pdc=frames().pdc + 1j)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not even numpy's ComplexWarning
        with pytest.raises(ReplayFormatError, match=r"'pdc' is complex \(complex128\)"):
            load_npz(path)
    path = save_npz(tmp_path / "rec.npz", frames())
    pac = frames().pac.copy()
    pac[4, 7] = np.nan
    resave(path, pac=pac)
    with pytest.raises(ReplayFormatError, match=r"'pac' row 4 column 7 is nan"):
        load_npz(path)


# --- not regular files -------------------------------------------------------------------------


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path, suffix):
    fifo = tmp_path / f"pipe{suffix}"
    os.mkfifo(fifo)
    with pytest.raises(ReplayFormatError, match=r"pipe\.\w+: the path is a FIFO"):
        _replay.load_recording(fifo)
    trace = tmp_path / "trace.npz"
    os.mkfifo(trace)
    with pytest.raises(RecordingError, match="is a FIFO"):
        load_recording(tmp_path)  # the run directory's trace.npz


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="needs /dev/zero")
def test_a_device_behind_a_symlink_is_refused(tmp_path):
    for name in ("zero.csv", "zero.npz"):
        (tmp_path / name).symlink_to("/dev/zero")
        with pytest.raises(ReplayFormatError, match="the path is a device, not a regular file"):
            _replay.load_recording(tmp_path / name)
    with pytest.raises(RecordingError, match="is a device"):
        load_labels(tmp_path / "zero.npz")


# --- trace recordings --------------------------------------------------------------------------


def trace(n: int = 8) -> dict[str, np.ndarray]:
    t = 0.01 * np.arange(1, n + 1)
    return {"sensor/wrist/timestamps_s": t, "sensor/wrist/force_n": np.ones((n, 2)),
            "sensor/wrist/force_n/unit": np.array("N")}


def test_trace_complex_channels_and_non_class_labels_are_refused(tmp_path):
    arrays = trace()
    arrays["sensor/wrist/force_n"] = arrays["sensor/wrist/force_n"] + 2j
    np.savez(tmp_path / "trace.npz", **arrays)
    with pytest.raises(RecordingError, match=r"'sensor/wrist/force_n' is complex"):
        load_recording(tmp_path)
    for label in (7.5, -1.0, np.inf):
        state = np.zeros(8)
        state[2] = label
        np.savez(tmp_path / "labels.npz", timestamps_s=0.01 * np.arange(8), state=state)
        with pytest.raises(RecordingError, match=rf"labels\.npz: 'state' row 2 is {label:g}"):
            load_labels(tmp_path / "labels.npz")
    np.savez(tmp_path / "labels.npz", timestamps_s=np.array([0.0, np.inf]), state=np.zeros(2))
    with pytest.raises(RecordingError, match=r"'timestamps_s' row 1 is inf"):
        load_labels(tmp_path / "labels.npz")


def test_trace_declaring_a_huge_sensor_is_refused_before_loading(tmp_path):
    path = tmp_path / "trace.npz"
    header = {"descr": "<f8", "fortran_order": False, "shape": (20_000_000, 22)}
    with zipfile.ZipFile(path, "w") as archive:
        with archive.open("sensor/wrist/pac.npy", "w") as member:
            np.lib.format.write_array_header_1_0(member, header)
        # Members the replay never reads do not count.
        with archive.open("world/huge.npy", "w") as member:
            np.lib.format.write_array_header_1_0(member, header)
    with pytest.raises(RecordingError, match=r"trace\.npz: the file declares arrays of 3.52 GB "
                       r"\('sensor/wrist/pac' 20000000 x 22 float64\)"):
        load_recording(path)


# --- memory ------------------------------------------------------------------------------------

_PEAK = """
import resource, sys
from hapticframe_biotac._replay import load_csv
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
frames = load_csv(sys.argv[1]).frames
print(before, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, len(frames))
"""


def test_peak_memory_of_a_csv_load_is_the_frames_plus_a_block(tmp_path):
    n = 30_000
    table = np.random.default_rng(5).integers(0, 4096, (n, len(HEADER))).astype(float)
    table[:, 0] = 100.0 + 0.01 * np.arange(n)
    path = tmp_path / "big.csv"
    np.savetxt(path, table, fmt=["%.2f"] + ["%d"] * (len(HEADER) - 1), delimiter=",",
               header=",".join(HEADER), comments="")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    out = subprocess.run([sys.executable, "-c", _PEAK, str(path)], capture_output=True,
                         text=True, env=env, check=True).stdout.split()
    before_kib, peak_kib, rows = map(int, out)
    assert rows == n
    frames_bytes = n * 47 * 8  # 11 MB of float64 frames from a 6.5 MB file
    # The frames plus blocks of a few MB; the whole-file read this replaced peaked at about
    # 17 times the file (110 MB here).
    grown = (peak_kib - before_kib) * 1024
    assert grown < frames_bytes + 30e6, (grown, path.stat().st_size)
