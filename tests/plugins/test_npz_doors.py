"""Saved ``.npz`` artifacts of the plugins (the response library, the raking estimator's
weights) refuse hostile files located at the file (issue 36 §1): a FIFO, a member that
declares gigabytes, object and string arrays, a bare ``.npy``, a truncated archive."""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hapticframe_mpm_sand import bundled_library, load_library, save_library
from hapticframe_raking import RakingModel
from hapticframe_raking._estimator import pretrained_model_dir


def _npy(array: np.ndarray | None = None, *, shape: tuple[int, ...] = (),
         descr: str = "<f8") -> bytes:
    stream = io.BytesIO()
    if array is not None:
        np.lib.format.write_array(stream, array, allow_pickle=True)
    else:  # a header that declares ``shape`` and no data
        np.lib.format.write_array_header_1_0(
            stream, {"descr": descr, "fortran_order": False, "shape": shape})
    return stream.getvalue()


def _with_member(source: Path, target: Path, name: str, blob: bytes) -> Path:
    with zipfile.ZipFile(source) as src, zipfile.ZipFile(target, "w") as dst:
        for info in src.infolist():
            if info.filename != f"{name}.npy":
                dst.writestr(info, src.read(info))
        dst.writestr(f"{name}.npy", blob)
    return target


@pytest.fixture
def library(tmp_path: Path) -> Path:
    path = tmp_path / "library.npz"
    save_library(path, bundled_library())
    load_library(path)  # the intact file reads
    return path


@pytest.mark.parametrize(("blob", "says"), [
    (_npy(shape=(40_000, 40_000, 40)), "GB"),
    (_npy(np.array([{"a": 1}], dtype=object)), "Python objects"),
    (_npy(np.array(["1.0", "2.0"])), "not numbers"),
    (b"\x93NUMPY\x01\x00garbage", "header"),
])
def test_a_hostile_library_member_is_refused_naming_the_file(
        tmp_path: Path, library: Path, blob: bytes, says: str) -> None:
    bad = _with_member(library, tmp_path / "bad.npz", "ratio_x", blob)
    with pytest.raises(ValueError, match=says) as caught:
        load_library(bad)
    assert str(bad) in str(caught.value)


def test_a_bare_npy_and_a_truncated_library(tmp_path: Path, library: Path) -> None:
    np.save(tmp_path / "lib.npy", np.zeros(3))
    bare = tmp_path / "bare.npz"
    shutil.move(tmp_path / "lib.npy", bare)
    with pytest.raises(ValueError, match=r"bare\.npz.*single \.npy"):
        load_library(bare)
    cut = tmp_path / "cut.npz"
    cut.write_bytes(library.read_bytes()[: library.stat().st_size // 2])
    with pytest.raises(ValueError, match=r"cut\.npz.*truncated"):
        load_library(cut)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_as_a_library_is_refused_at_once(tmp_path: Path) -> None:
    fifo = tmp_path / "library.npz"
    os.mkfifo(fifo)
    code = ("from pathlib import Path\nfrom hapticframe_mpm_sand import load_library\n"
            f"try:\n    load_library(Path({str(fifo)!r}))\n"
            "except ValueError as exc:\n    print(exc)\n")
    try:  # a child process: a regression that blocks on the FIFO fails, not hangs
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=60, stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail("load_library blocked on a FIFO")
    assert done.returncode == 0 and "FIFO" in done.stdout and str(fifo) in done.stdout, done


@pytest.mark.parametrize(("member", "blob", "says"), [
    ("kernel", _npy(shape=(10**6, 10**5)), "GB"),
    ("kernel", _npy(np.array([{"a": 1}], dtype=object)), "Python objects"),
    ("bias", _npy(np.full(8, np.nan)), "finite"),
    ("mean", _npy(np.zeros((3, 3, 3))), "incomplete|do not fit"),
])
def test_a_hostile_estimator_is_refused_naming_its_directory(
        tmp_path: Path, member: str, blob: bytes, says: str) -> None:
    model = tmp_path / "estimator"
    shutil.copytree(pretrained_model_dir(), model)
    RakingModel.load(model)  # the intact copy reads
    weights = model / "weights.npz"
    _with_member(weights, tmp_path / "w.npz", member, blob).replace(weights)
    with pytest.raises(ValueError, match=says) as caught:
        RakingModel.load(model)
    assert str(model) in str(caught.value)
