"""``hapticframe recover``: what a killed run's (or a damaged) recording still holds, as a
complete, indexed recording written beside it.

The source is read record by record, never trusted further than it checks out: a chunk
that fails its CRC or cannot be decompressed is skipped and said so, and the reading goes
on with the next record (when a damaged length hides where that is, with the next chunk
found by its header). Channels and schemas the summary section repeats stand in for those
a skipped chunk held. Nothing is replaced in place:

- a killed run's directory (``DIR/.hapticframe-partial/run.mcap``): the recovered file is
  ``DIR/run.mcap``, the cut original moves to ``DIR/run.cut.mcap``, the other files the run
  had staged move into ``DIR``, and ``run.json`` ends as ``status: recovered``, listing
  them, with the next step;
- any other recording (a finished run's ``run.mcap`` with ``finished=True`` only, or a file
  named directly): ``NAME.recovered.mcap`` beside it, or ``out``.
"""

from __future__ import annotations

import json
import logging
import mmap
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime, timezone
from io import BytesIO
from pathlib import Path
from typing import Any

from hapticframe._atomic import TEMP_PREFIX, OutputError, atomic_path, output_error
from hapticframe._errors import RunError, UsageError
from hapticframe._lock import lock_directory
from hapticframe._version import __version__
from hapticframe.record._recording import (
    CHUNK_BYTES,
    MAGIC,
    RECORDING,
    _check_magic,
    find_recording,
)
from hapticframe.run._results import FINISHED, STAGING, write_json

__all__ = ["CUT_NAME", "Recovery", "recover", "recover_run"]

_log = logging.getLogger("hapticframe.recording")

#: Where a killed run's cut recording goes once recovered (beside the recovered ``run.mcap``).
CUT_NAME = "run.cut.mcap"
#: What the suffix of a recovered file written beside its source is.
RECOVERED_SUFFIX = ".recovered.mcap"

#: A chunk record's header: opcode 0x06, its length, start and end times, uncompressed size
#: and CRC, then the compression's name (``zstd``, ``lz4`` or none).
_CHUNK_HEAD = re.compile(
    rb"\x06(.{8}).{28}(\x04\x00\x00\x00zstd|\x03\x00\x00\x00lz4|\x00\x00\x00\x00)(.{8})",
    re.DOTALL)
_OPCODES = frozenset(range(0x01, 0x11))
_FOOTER = 0x02
_CHUNK = 0x06


@dataclass
class Recovery:
    """What :func:`recover` read back, and what it skipped."""

    source: Path
    target: Path
    counts: dict[str, int]
    start_s: float
    end_s: float
    #: How the reading stopped when the file was cut ("" for a file read to its end).
    cut: str = ""
    #: Each part of the file that could not be read, where and why.
    skipped: list[str] = field(default_factory=list)
    #: Files moved into the run's directory (a killed run's staged results, its cut file).
    moved: list[str] = field(default_factory=list)
    #: What to do next (a line for the user).
    next_step: str = ""

    @property
    def messages(self) -> int:
        return sum(self.counts.values())


def _le(data: bytes) -> int:
    return int.from_bytes(data, "little")


def _next_chunk(view: Any, start: int) -> int | None:
    """The offset of the next plausible chunk header at or after ``start`` (None: none)."""
    for match in _CHUNK_HEAD.finditer(view, start):
        length = _le(match.group(1))
        data_length = _le(match.group(3))
        name = len(match.group(2)) - 4
        if length == 8 + 8 + 8 + 4 + 4 + name + 8 + data_length:
            return match.start()
    return None


def _parse(record: bytes) -> Any:
    """One record (opcode, length, body) parsed alone by the mcap library's own reader;
    None for a record type it does not know."""
    from mcap.stream_reader import StreamReader

    reader = StreamReader(BytesIO(record), skip_magic=True, emit_chunks=True)
    for parsed in reader.records:
        return parsed
    return None


def _parse_one(record: bytes) -> Any:
    try:
        return _parse(record)
    except Exception as exc:
        if type(exc).__name__ == "EndOfFile":
            return None  # a record type the reader skips: it read on past the end
        raise


def _chunk_records(chunk: Any) -> list[Any]:
    from mcap.stream_reader import breakup_chunk

    return list(breakup_chunk(chunk, validate_crc=True))


def _why(exc: BaseException) -> str:
    from mcap.stream_reader import CRCValidationError

    if isinstance(exc, CRCValidationError):
        return (f"its CRC check fails (stored {exc.expected:#010x}, computed "
                f"{exc.actual:#010x}): the bytes were changed after they were written")
    if type(exc).__name__ == "ZstdError":
        return f"it cannot be decompressed ({exc}): the bytes were changed after they were written"
    return f"it cannot be read ({type(exc).__name__}{': ' + str(exc) if str(exc) else ''})"


def salvage(path: Path, skipped: list[str], cut: list[str]) -> Iterator[Any]:
    """Every readable record of ``path`` in file order, chunks opened; what could not be read
    goes into ``skipped``, how the reading stopped short of a footer into ``cut``."""
    with open(path, "rb") as stream:
        size = os.fstat(stream.fileno()).st_size
        if size <= len(MAGIC):
            cut.append(f"the file ends after {size} bytes, before its first record")
            return
        view = mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ)
        try:
            yield from _walk(view, size, skipped, cut)
        finally:
            view.close()


def _walk(view: Any, size: int, skipped: list[str], cut: list[str]) -> Iterator[Any]:
    pos = len(MAGIC)
    while pos < size:
        if size - pos < 9:
            cut.append(f"the file ends inside a record's header, at byte {size} (cut while "
                       "being written)")
            return
        opcode, length = view[pos], _le(view[pos + 1:pos + 9])
        end = pos + 9 + length
        if opcode not in _OPCODES or end > size:
            resume = _next_chunk(view, pos + 1)
            if resume is None:
                if opcode in _OPCODES:
                    cut.append(f"the file ends inside a record, at byte {size} (the record "
                               f"at byte {pos} is {length} bytes long: cut while being "
                               "written)")
                else:
                    skipped.append(f"bytes {pos}-{size}: no readable record (a damaged "
                                   "record header), and no chunk after it")
                return
            skipped.append(f"bytes {pos}-{resume}: a damaged record header (opcode "
                           f"{opcode:#04x}, length {length}); read on from the next chunk, at "
                           f"byte {resume}")
            pos = resume
            continue
        try:
            record = _parse_one(bytes(view[pos:end]))
            inner = _chunk_records(record) if opcode == _CHUNK else None
        except Exception as exc:  # a damaged record: say which and why, read on
            what = "the chunk" if opcode == _CHUNK else f"the record (opcode {opcode:#04x})"
            skipped.append(f"{what} at bytes {pos}-{end} is skipped: {_why(exc)}")
            pos = end
            continue
        if inner is not None:
            yield from inner
        elif record is not None:
            yield record
        if opcode == _FOOTER:
            return
        pos = end
    cut.append(f"the file ends at byte {size} without its footer (cut between records)")


def recover(source: Path, target: Path) -> Recovery:
    """Read ``source`` record by record (see :func:`salvage`) and write every whole message
    to ``target`` as a complete, indexed recording (atomically). ``target`` is never
    ``source``.

    Raises :class:`UsageError` (exit status 2) when ``source`` is not an MCAP file or is
    ``target``.
    """
    from mcap.records import Channel, Message, Metadata, Schema
    from mcap.writer import CompressionType, Writer

    _check_magic(source)
    if source.resolve() == target.resolve():
        raise UsageError(f"recover never writes over what it reads ({source}): give another "
                         "--out")
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    # First pass: every schema and channel the file still holds (the summary repeats them,
    # so messages whose definitions sat in a skipped chunk can still be written).
    for record in salvage(source, [], []):
        if isinstance(record, Schema):
            schemas.setdefault(record.id, record)
        elif isinstance(record, Channel):
            channels.setdefault(record.id, record)
    skipped: list[str] = []
    stop: list[str] = []
    counts: dict[str, int] = {}
    orphans = 0
    start_ns: int | None = None
    end_ns = 0
    with atomic_path(target) as temp, open(temp, "wb") as out:
        writer = Writer(out, chunk_size=CHUNK_BYTES, compression=CompressionType.ZSTD)
        writer.start(profile="", library=f"hapticframe {__version__} (recovered)")
        schema_ids: dict[int, int] = {}
        channel_ids: dict[int, int] = {}
        for record in salvage(source, skipped, stop):
            if isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None:
                    orphans += 1  # a message without its channel cannot be decoded
                    continue
                if record.channel_id not in channel_ids:
                    if channel.schema_id not in schema_ids and channel.schema_id in schemas:
                        s = schemas[channel.schema_id]
                        schema_ids[channel.schema_id] = writer.register_schema(
                            s.name, s.encoding, s.data)
                    channel_ids[record.channel_id] = writer.register_channel(
                        channel.topic, channel.message_encoding,
                        schema_ids.get(channel.schema_id, 0), dict(channel.metadata))
                writer.add_message(channel_ids[record.channel_id], record.log_time,
                                   record.data, record.publish_time, record.sequence)
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
                start_ns = record.log_time if start_ns is None else min(start_ns, record.log_time)
                end_ns = max(end_ns, record.log_time)
        writer.finish()  # type: ignore[no-untyped-call]
        out.flush()
    if orphans:
        skipped.append(f"{orphans} messages whose channel was defined in a skipped part")
    first = (start_ns or 0) / 1e9
    return Recovery(source, target, counts, first, end_ns / 1e9 if counts else first,
                    stop[0] if stop else "", skipped)


def _read_record(path: Path) -> dict[str, Any] | None:
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return record if isinstance(record, dict) else None


def _beside(source: Path) -> Path:
    return source.with_name(source.name.removesuffix(".mcap") + RECOVERED_SUFFIX)


def recover_run(target: Path, out: Path | None = None, *, finished: bool = False) -> Recovery:
    """``hapticframe recover``: ``target`` is a run's directory or a recording file.

    A killed run's directory ends as a finished one (``status: recovered``, see the
    module's notes); a finished run's recording is read only with ``finished=True``, and
    rewritten beside it. The directory written into is locked meanwhile.

    Raises
    ------
    UsageError
        (exit status 2) ``target`` holds no recording; it is a finished run and
        ``finished`` is False; the file to write exists already; another command writes
        into the directory now.
    RunError
        Not one message could be read (exit status 1).
    """
    source = find_recording(target)
    run_dir = target if target.is_dir() else None
    record_path = (run_dir or source.parent) / "run.json"
    record = _read_record(record_path)
    status = record.get("status") if record is not None else None
    # A run killed before its end: its recording still staged, or its record unfinished.
    killed = run_dir is not None and (source.parent.name == STAGING or status == "running")
    if not killed and status in FINISHED and source.parent == record_path.parent \
            and source.name == RECORDING and not finished:
        raise UsageError(
            f"{source} is the recording of a finished run ({record_path.name}: status "
            f"{status}); recover reads it only when asked: pass --finished to write what it "
            f"still holds to {_beside(source).name} beside it (it is never replaced)")
    if out is None:
        out = run_dir / RECORDING if killed and run_dir is not None and not (
            run_dir / RECORDING).exists() else _beside(source)
    if out.exists() or out.is_symlink():
        raise UsageError(f"{out} exists already (an earlier recover?); recover never replaces "
                         "a file: move it away, or give another --out")
    folder = out.parent
    with lock_directory(folder, "recover"):
        recovery = recover(source, out)
        if not recovery.messages:
            out.unlink(missing_ok=True)
            raise RunError(f"not one message of {source} could be read"
                           + (f" ({'; '.join(recovery.skipped)})" if recovery.skipped else "")
                           + (f"; {recovery.cut}" if recovery.cut else "")
                           + f"; {source} is left as it was")
        if killed and run_dir is not None:
            _settle_killed(run_dir, source, recovery, record)
        elif record is not None and folder == record_path.parent:
            _list(record_path, record, [out.name])
        shown = run_dir if killed and run_dir is not None and out == run_dir / RECORDING \
            else out
        recovery.next_step = (f"hapticframe report {shown} writes a trace and figures from "
                              "it, beside the run's own")
    return recovery


def _settle_killed(run_dir: Path, source: Path, recovery: Recovery,
                   record: dict[str, Any] | None) -> None:
    """A killed run's staging folder, once its recording is recovered: the cut file and the
    other staged results move into the directory; ``run.json`` says ``recovered``."""
    staging = run_dir / STAGING
    moved: list[str] = []
    left: list[str] = []
    for entry in sorted(staging.iterdir()) if staging.is_dir() else []:
        if entry.name.startswith(TEMP_PREFIX):
            entry.unlink(missing_ok=True)  # a write the kill cut short: never a result
            continue
        name = CUT_NAME if entry == source else entry.name
        destination = run_dir / name
        if destination.exists() or destination.is_symlink() or entry.is_dir():
            left.append(entry.name)
            continue
        try:
            os.replace(entry, destination)
        except OSError as exc:
            raise output_error(destination, exc, "cannot move the result into place:") from exc
        moved.append(name)
    if not left:
        try:
            if staging.is_dir():
                staging.rmdir()
        except OSError:
            left.append("(the folder itself)")
    else:
        recovery.skipped.append(f"left in {staging} (a name already taken, or a folder): "
                                f"{', '.join(left)}")
    recovery.moved = moved
    if record is None:
        return
    files = [str(f) for f in record.get("files") or [] if isinstance(f, str)]
    final = {
        **record,
        "status": "recovered",
        "error": record.get("error") or ("the run was killed before it ended; its recording "
                                         "was recovered"),
        "files": sorted({*files, *moved, recovery.target.name}),
        "recovered": {
            "utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            "messages": recovery.messages,
            "cut": recovery.cut,
            "skipped": recovery.skipped,
            "next_step": f"hapticframe report {run_dir}",
        },
    }
    try:
        write_json(run_dir / "run.json", final)
    except OutputError as exc:
        _log.warning("%s", exc)


def _list(record_path: Path, record: dict[str, Any], names: list[str]) -> None:
    """List the recovered file in the run's record, so ``--overwrite`` may clear it."""
    listed = record.get("files")
    files: list[Any] = listed if isinstance(listed, list) else []
    missing = [n for n in names if n not in files]
    if missing:
        try:
            write_json(record_path, {**record, "files": sorted([*files, *missing])})
        except OutputError as exc:
            _log.warning("%s", exc)

