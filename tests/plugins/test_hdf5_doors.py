"""The HDF5 readers of the plugins (BOLT recordings, the authors' Keras models) refuse
hostile files located at file and dataset (issue 36 §1): links out of the file, dangling or
looping, damaged object headers, huge fill values and raw data stored in a FIFO."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

h5py = pytest.importorskip("h5py")

from hapticframe_biotac import ReplayFormatError, load_bolt, save_bolt  # noqa: E402
from hapticframe_raking import KerasModelError, load_keras_model  # noqa: E402
from tests.support.bolt_fixture import bolt_trials  # noqa: E402


def _keras(path: Path) -> Path:
    config = {"class_name": "Sequential", "config": {"layers": [
        {"class_name": "InputLayer", "config": {"batch_input_shape": [None, 5, 2]}},
        {"class_name": "LSTM", "config": {"name": "lstm", "units": 1, "activation": "tanh",
                                          "recurrent_activation": "sigmoid",
                                          "return_sequences": True}}]}}
    with h5py.File(path, "w", libver="latest") as f:
        f.attrs["model_config"] = json.dumps(config)
        g = f.create_group("model_weights").create_group("lstm")
        g.attrs["weight_names"] = [b"k", b"r", b"b"]
        g["k"], g["r"], g["b"] = np.ones((2, 4)), np.ones((1, 4)), np.zeros(4)
    return path


def _bolt(path: Path) -> Path:
    return save_bolt(path, bolt_trials(np.random.default_rng(0), "x", count=1, n=60))


# Each edit replaces one dataset the reader needs (BOLT: x_01/finger_0/pdc, Keras: the
# LSTM's kernel) or one group on its way.
def _dangling(f: Any, parent: str, leaf: str) -> None:
    del f[f"{parent}/{leaf}"]
    f[f"{parent}/{leaf}"] = h5py.SoftLink("/nowhere/at/all")


def _loop(f: Any, parent: str, leaf: str) -> None:
    del f[f"{parent}/{leaf}"]
    f[f"{parent}/{leaf}"] = h5py.SoftLink(f"{parent}/other")
    f[f"{parent}/other"] = h5py.SoftLink(f"{parent}/{leaf}")


def _missing_file(f: Any, parent: str, leaf: str) -> None:
    del f[f"{parent}/{leaf}"]
    f[f"{parent}/{leaf}"] = h5py.ExternalLink("missing.h5", "/data")


def _itself(f: Any, parent: str, leaf: str) -> None:
    del f[f"{parent}/{leaf}"]
    f[f"{parent}/{leaf}"] = h5py.ExternalLink(f.filename, f"{parent}/{leaf}")


def _fill(f: Any, parent: str, leaf: str) -> None:
    del f[f"{parent}/{leaf}"]
    f[parent].create_dataset(leaf, shape=(220_000_000,), dtype="f8", fillvalue=1.0)


EDITS: list[tuple[Callable[..., None], str]] = [
    (_dangling, "not in the file"), (_loop, "loop"), (_missing_file, "external link"),
    (_itself, "external link"), (_fill, "220000000")]
READERS = [
    (_bolt, load_bolt, ReplayFormatError, "/x_01/finger_0", "pdc"),
    (_keras, load_keras_model, KerasModelError, "/model_weights/lstm", "k"),
]


@pytest.mark.parametrize(("edit", "says"), EDITS)
@pytest.mark.parametrize(("write", "load", "error", "parent", "leaf"), READERS)
def test_hostile_links_and_dataspaces_are_refused_located(
        tmp_path: Path, edit: Any, says: str, write: Any, load: Any, error: Any, parent: str,
        leaf: str) -> None:
    path = write(tmp_path / "m.h5")
    load(path)  # the intact file reads
    with h5py.File(path, "a") as f:
        edit(f, parent, leaf)
    with pytest.raises(error) as caught:
        load(path)
    message = str(caught.value)
    assert str(path) in message and says in message and leaf in message, message


@pytest.mark.parametrize(("write", "load", "error", "parent", "leaf"), READERS)
def test_a_flipped_bit_in_an_object_header_is_refused_located(
        tmp_path: Path, write: Any, load: Any, error: Any, parent: str, leaf: str) -> None:
    path = write(tmp_path / "m.h5")
    with h5py.File(path, "a", libver="latest") as f:  # rewrite with signed object headers
        data = np.asarray(f[f"{parent}/{leaf}"])
        del f[f"{parent}/{leaf}"]
        f[parent].create_group("holder")
        f[f"{parent}/{leaf}"] = data
    blob = bytearray(path.read_bytes())
    headers = [m.start() for m in re.finditer(b"OHDR", blob)]
    blob[headers[-1] + 4] ^= 0x04  # the version byte of the newest object's header
    path.write_bytes(bytes(blob))
    with pytest.raises(error) as caught:
        load(path)
    assert str(path) in str(caught.value), caught.value


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize(("write", "load", "error", "parent", "leaf"), READERS)
def test_raw_data_in_a_fifo_is_refused_at_once(tmp_path: Path, write: Any, load: Any,
                                               error: Any, parent: str, leaf: str) -> None:
    path = write(tmp_path / "m.h5")
    fifo = tmp_path / "raw.bin"
    os.mkfifo(fifo)
    with h5py.File(path, "a") as f:
        shape, dtype = f[f"{parent}/{leaf}"].shape, f[f"{parent}/{leaf}"].dtype
        del f[f"{parent}/{leaf}"]
        f[parent].create_dataset(leaf, shape=shape, dtype=dtype,
                                 external=[(str(fifo), 0, int(np.prod(shape)) * 8)])
    # A child process, so that a regression that blocks on the FIFO fails, not hangs.
    code = (f"from {load.__module__.split('.')[0]} import {load.__name__} as load\n"
            f"try:\n    load({str(path)!r})\nexcept ValueError as exc:\n    print(exc)\n")
    try:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              timeout=60, stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        pytest.fail("the reader blocked on a FIFO")
    assert done.returncode == 0 and "outside the file" in done.stdout, done
    assert str(path) in done.stdout
