"""The ``tables``, ``hdf5`` and ``artifacts`` families of ``hapticframe bench fuzz`` (issue 36
§1): hostile files through the doors added after the experiment loader.

* ``tables``: ``hapticframe import`` of a CSV file, an xlsx workbook or an HDF5 file with a
  layout, one of them made hostile (a cell past csv's field limit, a FIFO, digits of other
  scripts or with ``_``, cells far apart with and without a dimension record, a DTD with an
  entity or an entity bomb, soft links dangling or looping, external links, a 220 M-value
  fill, raw data in a FIFO; a layout with a reserved name, a line read twice, a bad shape,
  a rate so small its steps overflow, classes named twice, a name of 1000 characters), or
  damaged (cut, bits flipped, junk);
* ``hdf5``: a BOLT recording (:func:`hapticframe_biotac.load_bolt`) and a Keras model file
  (:func:`hapticframe_raking.load_keras_model`) with the same HDF5 attacks, NaN, a string
  dataset, a wrong shape, and for Keras a ``model_config`` that is not JSON, nests deeply or
  holds a ``Lambda`` layer;
* ``artifacts``: the response library (:func:`hapticframe_mpm_sand.load_library`) and the
  raking estimator's saved weights (``RakingModel.load``): members declaring gigabytes,
  object, string and NaN arrays, a member missing, a bare ``.npy``, cut, emptied, flipped,
  junk, a FIFO, a ``model.json`` that is not strict JSON.

Each case is run in a forked child with a time limit (a hang is a finding, not a hung
bench). ``tables`` goes through the command line's ``main`` (exit status and message);
the loaders of the other two are called as a build calls them (a ``ValueError`` naming the
file is the refusal a build turns into exit 2). Every file of the case is hashed before and
after: one changed or gone is ``lost_or_mixed``. A case is hostile (it must be refused: an
exit 0 is ``accepted_invalid``, data accepted silently), damaged in a way no reader can
always see (bits flipped in data: refused or accepted), or intact (it must be read).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import select
import shutil
import signal
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe_bench._fuzz_common import Case, Outcome, compare_snapshots, snapshot

__all__ = ["DOOR_FAMILIES", "check_door_case", "generate_door_cases", "run_forked"]

DOOR_FAMILIES = ("tables", "hdf5", "artifacts")
#: Seconds a case may take in its child before it counts as a hang.
CASE_TIMEOUT_S = 30.0
HOSTILE, MAYBE, INTACT = "hostile", "maybe", "intact"

TABLE_KINDS: tuple[tuple[str, str], ...] = (
    ("none", INTACT), ("long_cell", HOSTILE), ("fifo", HOSTILE), ("digits", HOSTILE),
    ("reserved_name", HOSTILE), ("line_twice", HOSTILE), ("bad_shape", HOSTILE),
    ("tiny_rate", HOSTILE), ("duplicate_classes", HOSTILE), ("long_name", HOSTILE),
    ("far_cell", HOSTILE), ("dtd", HOSTILE), ("h5_link", HOSTILE), ("h5_fill", HOSTILE),
    ("h5_external", HOSTILE), ("truncate", MAYBE), ("flip", MAYBE), ("junk", MAYBE))
HDF5_KINDS: tuple[tuple[str, str], ...] = (
    ("none", INTACT), ("dangling", HOSTILE), ("loop", HOSTILE), ("external_missing", HOSTILE),
    ("external_self", HOSTILE), ("fill", HOSTILE), ("raw_fifo", HOSTILE), ("nan", HOSTILE),
    ("strings", HOSTILE), ("wrong_shape", HOSTILE), ("junk", HOSTILE), ("flip_header", MAYBE),
    ("flip", MAYBE), ("truncate", MAYBE), ("bad_config", HOSTILE))
ARTIFACT_KINDS: tuple[tuple[str, str], ...] = (
    ("none", INTACT), ("huge_member", HOSTILE), ("object_member", HOSTILE),
    ("string_member", HOSTILE), ("nan_member", HOSTILE), ("missing_member", HOSTILE),
    ("bare_npy", HOSTILE), ("truncate", HOSTILE), ("empty", HOSTILE), ("junk", HOSTILE),
    ("fifo", HOSTILE), ("flip", MAYBE), ("bad_json", HOSTILE))

LAYOUT = """\
schema_version: 1
name: fuzz
rate_hz: 10.0
channels:
  force: {lines: [1, 2], unit: N}
labels:
  side: {line: 3, classes: [left, right]}
position: {lines: [4, 5, 6], unit: m}
"""


# --- running a case in a child ----------------------------------------------------------

def run_forked(call: Callable[[], tuple[int, str]], timeout_s: float = CASE_TIMEOUT_S
               ) -> tuple[str, int, str]:
    """``call()`` in a forked child: ``("done", code, text)``, ``("timeout", -1, "")`` when it
    ran past ``timeout_s`` (the child is killed), or ``("crashed", signal, "")``."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: run, report, leave without running the parent's handlers
        os.close(read_end)
        try:
            code, text = call()
        except BaseException as exc:
            code, text = 99, f"internal error: {type(exc).__name__}: {exc}"
        data = json.dumps([code, text[-4000:]]).encode()
        with contextlib.suppress(OSError):
            while data:
                data = data[os.write(write_end, data):]
        os._exit(0)
    os.close(write_end)
    chunks: list[bytes] = []
    deadline = time.monotonic() + timeout_s
    try:
        while True:
            left = deadline - time.monotonic()
            ready = select.select([read_end], [], [], max(left, 0.0))[0] if left > 0 else []
            if not ready:
                os.kill(pid, signal.SIGKILL)
                os.waitpid(pid, 0)
                return "timeout", -1, ""
            chunk = os.read(read_end, 65536)
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(read_end)
    _, status = os.waitpid(pid, 0)
    if not chunks:
        return "crashed", os.WTERMSIG(status) if os.WIFSIGNALED(status) else status, ""
    code, text = json.loads(b"".join(chunks).decode())
    return "done", int(code), str(text)


def _cli(args: list[str]) -> Callable[[], tuple[int, str]]:
    def call() -> tuple[int, str]:
        from hapticframe.cli import main

        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main(args)
        return code, err.getvalue()
    return call


def _loader(load: Callable[[], Any]) -> Callable[[], tuple[int, str]]:
    def call() -> tuple[int, str]:
        try:
            load()
        except ValueError as exc:  # what a build turns into exit 2, located at the component
            return 2, f"error: {exc}"
        return 0, ""
    return call


# --- cases --------------------------------------------------------------------------------

def generate_door_cases(family: str, count: int, seed: int) -> list[Case]:
    """``count`` cases of ``family``: each kind in turn, its details drawn (seeded)."""
    kinds = {"tables": TABLE_KINDS, "hdf5": HDF5_KINDS, "artifacts": ARTIFACT_KINDS}[family]
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(count):
        kind, expect = kinds[k % len(kinds)]
        target = {"tables": ("csv", "xlsx", "h5"), "hdf5": ("bolt", "keras"),
                  "artifacts": ("library", "estimator")}[family][int(rng.integers(3 if
                                                                    family == "tables" else 2))]
        data = {"target": target, "expect": expect, "seed": int(rng.integers(2**31)),
                "fraction": float(rng.random()), "bits": int(rng.integers(1, 17)),
                "variant": int(rng.integers(4))}
        cases.append(Case(family, kind, f"{target} {kind} (variant {data['variant']})", data))
    return cases


def check_door_case(case: Case, workdir: Path) -> Outcome:
    """Make the case's files, run its door in a child, classify (see the module's notes)."""
    started = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    inputs = workdir / "in"
    inputs.mkdir(exist_ok=True)
    try:
        what, call, names, result = _prepare(case, inputs, workdir / "out")
    except _NotApplicable as exc:
        return Outcome(case, "skipped", True, str(exc), time.perf_counter() - started)
    before = snapshot(inputs)
    status, code, text = run_forked(call)
    seconds = time.perf_counter() - started
    problems = compare_snapshots(before, snapshot(inputs))
    if problems:
        return Outcome(case, "lost_or_mixed", False, f"{what}; {'; '.join(problems)}", seconds)
    last = text.strip().splitlines()[-1] if text.strip() else ""
    expect = case.data["expect"]
    if status == "timeout":
        return Outcome(case, "timeout", False, f"{what}; no end within {CASE_TIMEOUT_S:g} s",
                       seconds)
    if status == "crashed":
        return Outcome(case, "unexpected", False, f"{what}; the child died ({code})", seconds)
    if "internal error" in text or "Traceback (most recent call last)" in text:
        return Outcome(case, "internal_error", False, f"{what}; {last[:250]}", seconds)
    if code == 2:
        if not any(name in text for name in names):
            return Outcome(case, "unlocated", False, f"{what}; exit 2 naming none of "
                           f"{[n[-40:] for n in names]}: {last[:200]}", seconds)
        if expect == INTACT:
            return Outcome(case, "refused_intact", False, f"{what}; {last[:250]}", seconds)
        return Outcome(case, "refused", True, f"{what}; {last[:200]}", seconds)
    if code == 0:
        if expect == HOSTILE:
            return Outcome(case, "accepted_invalid", False, f"{what}; exit 0", seconds)
        null = result() if result is not None else None
        if null:
            return Outcome(case, "null_result", False, f"{what}; {null}", seconds)
        return Outcome(case, "ran" if expect == INTACT else "accepted", True, what, seconds)
    if code == 1 and last.startswith("error:"):
        return Outcome(case, "failed_clean", True, f"{what}; {last[:200]}", seconds)
    return Outcome(case, "unexpected", False, f"{what}; exit {code}: {last[:200]}", seconds)


class _NotApplicable(Exception):
    """A case this machine cannot make (no FIFOs)."""


def _prepare(case: Case, inputs: Path, out: Path) -> tuple[
        str, Callable[[], tuple[int, str]], tuple[str, ...], Callable[[], str | None] | None]:
    if case.family == "tables":
        return _prepare_table(case, inputs, out)
    if case.family == "hdf5":
        return _prepare_hdf5(case, inputs)
    return _prepare_artifact(case, inputs)


def _fifo(path: Path) -> Path:
    if not hasattr(os, "mkfifo"):
        raise _NotApplicable("no FIFOs on this system")
    os.mkfifo(path)
    return path


def _flip(path: Path, rng: np.random.Generator, bits: int) -> str:
    blob = bytearray(path.read_bytes())
    for offset in rng.integers(0, len(blob), bits):
        blob[int(offset)] ^= 1 << int(rng.integers(8))
    path.write_bytes(bytes(blob))
    return f"{bits} bit(s) flipped in {path.name}"


def _cut(path: Path, fraction: float) -> str:
    blob = path.read_bytes()
    cut = int(fraction * len(blob))
    path.write_bytes(blob[:cut])
    return f"{path.name} cut at byte {cut} of {len(blob)}"


def _junk(path: Path, rng: np.random.Generator) -> str:
    size = max(16, path.stat().st_size if path.exists() else 512)
    path.write_bytes(rng.integers(0, 256, size, dtype=np.uint8).tobytes())
    return f"{path.name} replaced by {size} random bytes"


# --- tables -------------------------------------------------------------------------------

def _table_rows(rng: np.random.Generator, steps: int) -> list[list[Any]]:
    return [rng.random(steps).tolist(), rng.random(steps).tolist(),
            rng.integers(0, 2, steps).tolist(), [0.1] * steps,
            np.linspace(0.0, 0.4, steps).tolist(), [-0.02] * steps]


def _write_csv(path: Path, rows: list[list[Any]]) -> Path:
    path.write_text("\n".join(",".join(str(v) for v in row) for row in rows) + "\n",
                    encoding="utf-8")
    return path


def _write_xlsx(path: Path, rows: list[list[Any]], far: str | None = None) -> Path:
    import openpyxl

    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "trial"
    for row in rows:
        sheet.append(row)
    if far is not None:
        sheet[far] = 1.0
    book.save(path)
    return path


def _rewrite_sheet(path: Path, edit: Callable[[str], str]) -> None:
    with zipfile.ZipFile(path) as src:
        members = {info.filename: src.read(info) for info in src.infolist()}
    name = "xl/worksheets/sheet1.xml"
    members[name] = edit(members[name].decode("utf-8")).encode("utf-8")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as dst:
        for member, blob in members.items():
            dst.writestr(member, blob)


def _write_h5_table(path: Path, rows: list[list[Any]], extra: Callable[[Any], None] | None = None
                    ) -> Path:
    import h5py

    with h5py.File(path, "w") as f:
        f.create_group("t1")["data"] = np.array(rows, float)
        if extra is not None:
            extra(f)
    return path


_DIGITS = ("1_0", "\u0661\u0662", "\uff11\uff12", "\u0967\u0968")
_DTDS = ('<!DOCTYPE worksheet [<!ENTITY e "0.5">]>',
         '<!DOCTYPE worksheet [<!ENTITY a "ha">' + "".join(
             f'<!ENTITY {c} "{("&" + p + ";") * 10}">'
             for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "]>",
         '<!DOCTYPE worksheet SYSTEM "file:///etc/passwd">')


def _layout_edit(kind: str, variant: int) -> tuple[str, str]:
    edits = {
        "reserved_name": [("  force:", "  timestamps_s:"), ("  side:", "  timestamps_s:"),
                          ("  side:", "  position_m:"), ("  force:", "  movement_index:")],
        "line_twice": [("{line: 3,", "{line: 2,"), ("lines: [4, 5, 6]", "lines: [4, 4, 6]"),
                       ("lines: [4, 5, 6]", "lines: [4, 5, 3]"),
                       ("lines: [4, 5, 6]", "lines: [1, 5, 6]")],
        "bad_shape": [("unit: N}", "unit: N, shape: [-1, -2]}"),
                      ("unit: N}", "unit: N, shape: [1, 2, 1]}"),
                      ("unit: N}", "unit: N, shape: [2, 1]}"),
                      ("unit: N}", "unit: N, shape: [0, 2]}")],
        "tiny_rate": [("rate_hz: 10.0", "rate_hz: 1.0e-320"), ("rate_hz: 10.0", "rate_hz: 1.0e-9"),
                      ("rate_hz: 10.0", "rate_hz: 0"), ("rate_hz: 10.0", "rate_hz: 5.0e-324")],
        "duplicate_classes": [("classes: [left, right]", "classes: [left, left]")] * 4,
        "long_name": [("  force:", "  f" + "o" * 1000 + ":")] * 4,
    }
    return edits[kind][variant % len(edits[kind])]


def _prepare_table(case: Case, inputs: Path, out: Path) -> tuple[
        str, Callable[[], tuple[int, str]], tuple[str, ...], Callable[[], str | None]]:
    import h5py

    rng = np.random.default_rng(case.data["seed"])
    kind, variant, target = case.kind, case.data["variant"], case.data["target"]
    rows = _table_rows(rng, int(rng.integers(3, 40)))
    layout_text = LAYOUT
    if kind in ("reserved_name", "line_twice", "bad_shape", "tiny_rate", "duplicate_classes",
                "long_name"):
        old, new = _layout_edit(kind, variant)
        layout_text = LAYOUT.replace(old, new, 1)
    layout = inputs / "layout.yaml"
    layout.write_text(layout_text, encoding="utf-8")
    what = kind
    if kind in ("long_cell", "fifo"):
        target = "csv"
    if kind in ("far_cell", "dtd"):
        target = "xlsx"
    if kind.startswith("h5_"):
        target = "h5"
    if kind == "digits":
        rows[int(rng.integers(0, 2))][0] = _DIGITS[variant % len(_DIGITS)]
        target = "csv" if target == "h5" else target
    if kind == "long_cell":
        rows += [[], ["x" * int(rng.integers(131_073, 400_000))]]
    table: Path
    if target == "csv":
        table = _write_csv(inputs / "trial.csv", rows)
        if kind == "fifo":
            folder = inputs / "trials"
            folder.mkdir()
            _write_csv(folder / "a.csv", rows)
            fifo = _fifo(folder / "b.csv")
            table.unlink()
            table = folder if variant % 2 else fifo
            what = f"a FIFO as {'one of the tables' if variant % 2 else 'the table'}"
    elif target == "xlsx":
        far = ("XFD1048576", "XFD1048576", "ZZ500000", "ZZ500000")[variant] \
            if kind == "far_cell" else None
        table = _write_xlsx(inputs / "trials.xlsx", rows, far)
        if kind == "far_cell" and variant % 2:
            _rewrite_sheet(table, lambda xml: re.sub(r"<dimension [^>]*/>", "", xml))
            what = f"a cell at {far}, no dimension record"
        elif kind == "far_cell":
            what = f"a cell at {far}"
        if kind == "dtd":
            dtd = _DTDS[variant % len(_DTDS)]
            _rewrite_sheet(table, lambda xml: '<?xml version="1.0"?>\n' + dtd + "\n"
                           + re.sub(r"^<\?xml[^>]*\?>\s*", "", xml))
    else:
        def extra(f: Any) -> None:
            if kind == "h5_link":
                link = [h5py.SoftLink("/nowhere/data"), h5py.SoftLink("/t3"),
                        h5py.ExternalLink("missing.h5", "/t1"),
                        h5py.ExternalLink(str(inputs / "trials.h5"), "/t2")][variant]
                if variant == 0:
                    f.create_group("t2")["data"] = link
                else:
                    f["t2"] = link
                    if variant == 1:
                        f["t3"] = h5py.SoftLink("/t2")
            elif kind == "h5_fill":
                f.create_group("t2").create_dataset("data", shape=(10, 22_000_000),
                                                    dtype="f8", fillvalue=1.0)
            elif kind == "h5_external":
                raw = inputs / "raw.bin"
                if variant % 2:
                    _fifo(raw)
                else:
                    raw.write_bytes(np.zeros(6 * 5).tobytes())
                f.create_group("t2").create_dataset("data", shape=(6, 5), dtype="f8",
                                                    external=[(str(raw), 0, 6 * 5 * 8)])
        table = _write_h5_table(inputs / "trials.h5", rows, extra)
    if kind == "truncate":
        what = _cut(table, case.data["fraction"])
    elif kind == "flip":
        what = _flip(table, rng, case.data["bits"])
    elif kind == "junk":
        what = _junk(table, rng)

    def result() -> str | None:
        trace = out / "trace.npz"
        if not trace.is_file():
            return "exit 0 without trace.npz"
        with np.load(trace, allow_pickle=False) as arrays:
            force = arrays["sensor/tactile/force"]
            t = arrays["sensor/tactile/timestamps_s"]
        if force.size == 0 or not np.all(np.isfinite(force)) or not np.all(np.isfinite(t)):
            return "exit 0 with an empty or non-finite force"
        return None

    args = ["import", str(table), "--layout", str(layout), "--out", str(out)]
    return what, _cli(args), (table.name, layout.name), result


# --- hdf5 ---------------------------------------------------------------------------------

def _write_bolt(path: Path, rng: np.random.Generator) -> tuple[str, str]:
    import h5py

    n = int(rng.integers(20, 120))
    with h5py.File(path, "w", libver="latest") as f:
        group = f.create_group("trial_01")
        group["timestamps"] = (1_400_000_000 + np.arange(n) // 100).astype(np.int64)
        for finger in ("finger_0", "finger_1"):
            sub = group.create_group(finger)
            sub["pac"] = rng.integers(1800, 2200, (n, 22))
            sub["electrodes"] = rng.integers(2000, 3000, (n, 19))
            for channel in ("pdc", "tac", "tdc"):
                sub[channel] = rng.integers(1500, 2500, n)
    return "/trial_01/finger_0", "pdc"


def _write_keras(path: Path, rng: np.random.Generator) -> tuple[str, str]:
    import h5py

    config = {"class_name": "Sequential", "config": {"layers": [
        {"class_name": "InputLayer", "config": {"batch_input_shape": [None, 5, 2]}},
        {"class_name": "LSTM", "config": {"name": "lstm", "units": 2, "activation": "tanh",
                                          "recurrent_activation": "sigmoid",
                                          "return_sequences": True}},
        {"class_name": "Dense", "config": {"name": "dense", "units": 1,
                                           "activation": "linear"}}]}}
    with h5py.File(path, "w", libver="latest") as f:
        f.attrs["model_config"] = json.dumps(config)
        weights = f.create_group("model_weights")
        lstm = weights.create_group("lstm")
        lstm.attrs["weight_names"] = [b"kernel", b"recurrent", b"bias"]
        lstm["kernel"], lstm["recurrent"] = rng.normal(size=(2, 8)), rng.normal(size=(2, 8))
        lstm["bias"] = np.zeros(8)
        dense = weights.create_group("dense")
        dense.attrs["weight_names"] = [b"kernel", b"bias"]
        dense["kernel"], dense["bias"] = rng.normal(size=(2, 1)), np.zeros(1)
    return "/model_weights/lstm", "kernel"


def _prepare_hdf5(case: Case, inputs: Path) -> tuple[
        str, Callable[[], tuple[int, str]], tuple[str, ...], None]:
    import h5py

    rng = np.random.default_rng(case.data["seed"])
    kind, variant, target = case.kind, case.data["variant"], case.data["target"]
    path = inputs / f"{target}.h5"
    parent, leaf = (_write_bolt if target == "bolt" else _write_keras)(path, rng)
    what = kind
    if kind in ("dangling", "loop", "external_missing", "external_self", "fill", "raw_fifo",
                "nan", "strings", "wrong_shape"):
        with h5py.File(path, "a") as f:
            old = f[f"{parent}/{leaf}"]
            shape, dtype = old.shape, old.dtype
            values = np.asarray(old)
            del f[f"{parent}/{leaf}"]
            here = f"{parent}/{leaf}"
            if kind == "dangling":
                f[here] = h5py.SoftLink("/nowhere/at/all")
            elif kind == "loop":
                f[here] = h5py.SoftLink(f"{parent}/other")
                f[f"{parent}/other"] = h5py.SoftLink(here)
            elif kind == "external_missing":
                f[here] = h5py.ExternalLink("missing.h5", "/data")
            elif kind == "external_self":
                f[here] = h5py.ExternalLink(str(path), here)
            elif kind == "fill":
                f[parent].create_dataset(leaf, shape=(220_000_000,), dtype="f8", fillvalue=1.0)
            elif kind == "raw_fifo":
                raw = inputs / "raw.bin"
                if variant % 2:
                    _fifo(raw)
                else:
                    raw.write_bytes(values.astype(dtype).tobytes())
                f[parent].create_dataset(leaf, shape=shape, dtype=dtype,
                                         external=[(str(raw), 0, values.nbytes)])
            elif kind == "nan":
                bad = values.astype(float)
                bad.flat[int(rng.integers(bad.size))] = [np.nan, np.inf, -np.inf, np.nan][variant]
                f[here] = bad
            elif kind == "strings":
                f[here] = np.array([b"x"] * max(1, values.size)).reshape(shape)
            else:
                f[here] = np.zeros((shape[0] + 1, *shape[1:], 2))
    elif kind == "bad_config":
        with h5py.File(path, "a") as f:
            if target == "keras":
                f.attrs["model_config"] = ["{not json", "[" * 100_000 + "]" * 100_000,
                                           json.dumps({"class_name": "Sequential", "config": {
                                               "layers": [{"class_name": "Lambda", "config": {
                                                   "name": "lstm"}}]}}),
                                           json.dumps([1, 2])][variant]
            else:
                f["trial_01/finger_1"].attrs["x"] = 1
                del f["trial_01/finger_1/electrodes"]
    elif kind == "junk":
        what = _junk(path, rng)
    elif kind == "flip_header":
        blob = bytearray(path.read_bytes())
        headers = [m.start() for m in re.finditer(b"OHDR", blob)]
        at = headers[int(rng.integers(len(headers)))] + int(rng.integers(4, 16))
        blob[min(at, len(blob) - 1)] ^= 1 << int(rng.integers(8))
        path.write_bytes(bytes(blob))
        what = f"a bit flipped in an object header at byte {at}"
    elif kind == "flip":
        what = _flip(path, rng, case.data["bits"])
    elif kind == "truncate":
        what = _cut(path, case.data["fraction"])

    def load() -> None:
        if target == "bolt":
            from hapticframe_biotac import load_bolt

            load_bolt(path)
        else:
            from hapticframe_raking import load_keras_model

            load_keras_model(path)

    return f"{target}: {what}", _loader(load), (str(path),), None


# --- artifacts ----------------------------------------------------------------------------

def _npy(array: np.ndarray | None = None, shape: tuple[int, ...] = ()) -> bytes:
    stream = io.BytesIO()
    if array is not None:
        np.lib.format.write_array(stream, array, allow_pickle=True)
    else:
        np.lib.format.write_array_header_1_0(
            stream, {"descr": "<f8", "fortran_order": False, "shape": shape})
    return stream.getvalue()


def _replace_member(path: Path, name: str, blob: bytes | None) -> None:
    with zipfile.ZipFile(path) as src:
        members = {i.filename: src.read(i) for i in src.infolist()}
    members.pop(f"{name}.npy", None)
    if blob is not None:
        members[f"{name}.npy"] = blob
    with zipfile.ZipFile(path, "w") as dst:
        for member, data in members.items():
            dst.writestr(member, data)


def _prepare_artifact(case: Case, inputs: Path) -> tuple[
        str, Callable[[], tuple[int, str]], tuple[str, ...], None]:
    rng = np.random.default_rng(case.data["seed"])
    kind, variant, target = case.kind, case.data["variant"], case.data["target"]
    if target == "library":
        from hapticframe_mpm_sand import bundled_library, save_library

        path = inputs / "library.npz"
        save_library(path, bundled_library())
        member, located = ("ratio_x", "free_drag_n", "depths_m", "settings")[variant], path
    else:
        from hapticframe_raking import pretrained_model_dir

        located = inputs / "estimator"
        shutil.copytree(pretrained_model_dir(), located)
        path = located / "weights.npz"
        member = ("kernel", "bias", "mean", "head_kernel")[variant]
    what = kind
    if kind == "huge_member":
        _replace_member(path, member, _npy(shape=(40_000, 40_000, 40)))
    elif kind == "object_member":
        _replace_member(path, member, _npy(np.array([{"a": 1}], dtype=object)))
    elif kind == "string_member":
        _replace_member(path, member, _npy(np.array(["1.0", "2.0"])))
    elif kind == "nan_member":
        with np.load(path, allow_pickle=False) as data:
            values = np.array(data[member], dtype=float)
        values.flat[int(rng.integers(values.size))] = np.nan
        _replace_member(path, member, _npy(values))
    elif kind == "missing_member":
        _replace_member(path, member, None)
    elif kind == "bare_npy":
        path.write_bytes(_npy(np.zeros(3)))
    elif kind == "truncate":
        what = _cut(path, min(case.data["fraction"], 0.99))
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "junk":
        what = _junk(path, rng)
    elif kind == "fifo":
        path.unlink()
        _fifo(path)
    elif kind == "flip":
        what = _flip(path, rng, case.data["bits"])
    elif kind == "bad_json":
        if target == "estimator":
            (located / "model.json").write_text(
                ['{"format": NaN}', "{", '{"a": 1, "a": 2}', "[" * 100_000][variant])
        else:
            path.write_bytes(b'{"depths_m": [0.01]}')
    if kind in ("huge_member", "object_member", "string_member", "nan_member",
                "missing_member"):
        what = f"{kind} {member}"

    def load() -> None:
        if target == "library":
            from hapticframe_mpm_sand import load_library

            load_library(path)
        else:
            from hapticframe_raking import RakingModel

            RakingModel.load(located)

    return f"{target}: {what}", _loader(load), (str(located),), None
