"""Writing what a run or a training run leaves behind: ``run.json``, ``metrics.json``,
``trace.npz`` and the JSON helpers ``hapticframe train`` shares.

``run.json`` records the status (``ok``, ``failed`` or ``interrupted`` with the signal),
the error, the seed, the versions of hapticframe, Python and every scientific dependency
that is installed, the git commit of the project when it is a git checkout, every
plugin's distribution and version, the resolved config and the files the run wrote.

Outputs are atomic. Every file is written to a temporary name beside its target, flushed
to disk and renamed (:func:`atomic_write`, :func:`atomic_path`, :func:`write_json`,
:func:`save_npz`), so a file is either complete or absent. A run's directory
(:class:`OutputDir`) tells the truth at every moment: ``run.json`` with
``status: running`` is written before anything is built; the run writes into a staging
folder inside the directory (``.hapticframe-partial``), whose files are moved into the
directory when the run ends, after ``run.json`` has listed them; ``run.json`` is then
rewritten with the final status and the list of files. A directory killed at any point
therefore holds either a finished run or a ``run.json`` that says ``running``, and
``--overwrite`` deletes exactly the files hapticframe listed, never a file it did not write.
"""

from __future__ import annotations

import functools
import json
import logging
import math
import os
import platform
import shutil
import subprocess
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from hapticframe._atomic import (
    TEMP_PREFIX,
    OutputError,
    atomic_path,
    atomic_write,
    output_error,
    remove_quietly,
    save_npz,
)
from hapticframe._errors import UsageError
from hapticframe._lock import DirectoryLock, lock_directory
from hapticframe._version import __version__

if TYPE_CHECKING:
    from hapticframe._config import Experiment
    from hapticframe.run._session import Session

__all__ = [
    "MIN_FREE_BYTES",
    "OutputDir",
    "OutputError",
    "RunSummary",
    "atomic_path",
    "atomic_write",
    "environment",
    "git_commit",
    "run_record",
    "save_npz",
    "write_json",
]

_log = logging.getLogger("hapticframe.results")

#: The free space ``--out`` must have before a run or a training run starts (bytes); the
#: environment variable ``HAPTICFRAME_MIN_FREE_MB`` or ``--min-free-mb`` change it.
MIN_FREE_BYTES = 50 * 1024 * 1024
MIN_FREE_ENV = "HAPTICFRAME_MIN_FREE_MB"
#: The folder inside ``--out`` that a run writes into until it ends.
STAGING = ".hapticframe-partial"
#: The statuses of a run (or training run) that has ended (``recovered``: a killed run whose
#: recording ``hapticframe recover`` rewrote).
FINISHED = ("ok", "failed", "interrupted", "recovered")

#: Distributions whose versions a run records when they are installed.
SCIENTIFIC_DISTRIBUTIONS = (
    "numpy",
    "scipy",
    "torch",
    "scikit-learn",
    "numba",
    "matplotlib",
    "pydantic",
    "pluggy",
    "PyYAML",
    "pyserial",
)


class RunSummary(dict[str, Any]):
    """The metrics of a finished run (a dict), plus where they were written (``out_dir``)."""

    def __init__(self, metrics: Mapping[str, Any], out_dir: Path) -> None:
        super().__init__(metrics)
        self.out_dir = out_dir


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def write_json(path: str | Path, data: Mapping[str, Any]) -> Path:
    """Write ``data`` atomically as sorted, indented JSON; NaN and infinities become null.

    Raises :class:`OutputError` (naming the file) when it cannot be written; whatever
    ``path`` held before is then left as it was.
    """
    clean = json.loads(json.dumps(data, default=_json_default, allow_nan=True))
    text = json.dumps(_nan_to_none(clean), indent=2, sort_keys=True, allow_nan=False)
    return atomic_write(path, text + "\n")


def _nan_to_none(value: Any) -> Any:
    # JSON has no NaN: an unknown figure is written as null, never as a bogus number.
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _nan_to_none(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_nan_to_none(v) for v in value]
    return value


@functools.lru_cache(maxsize=1)
def git_commit() -> str | None:
    """The commit of the git checkout hapticframe runs from, or None (not a checkout, no
    git, or any other failure: recording provenance never fails a run)."""
    try:
        root = Path(__file__).resolve().parents[2]  # <checkout>/hapticframe/run/_results.py
        if not (root / ".git").exists():
            return None
        done = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True, text=True, timeout=5, check=False,
        )
        commit = done.stdout.strip()
        if done.returncode != 0 or not commit:
            return None
        dirty = subprocess.run(
            ["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True, text=True, timeout=5, check=False,
        )
        return commit + ("-dirty" if dirty.returncode == 0 and dirty.stdout.strip() else "")
    except Exception:  # provenance is best effort, never a failure
        return None


@functools.lru_cache(maxsize=1)
def _dependency_versions() -> dict[str, str]:
    versions = {}
    for name in SCIENTIFIC_DISTRIBUTIONS:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            continue
        except Exception:  # a broken installation's metadata: skip it
            continue
    return versions


def environment() -> dict[str, Any]:
    """Versions and provenance for ``run.json`` and ``train.json``."""
    return {
        "hapticframe": __version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "git_commit": git_commit(),
        **_dependency_versions(),
    }


def plugin_records(experiment: Experiment) -> list[dict[str, Any]]:
    """Each component's id, kind, type and the distribution and version it came from."""
    return [
        {
            "id": e.id,
            "kind": e.kind.value,
            "type": e.type,
            "distribution": e.registered.source.distribution,
            "version": e.registered.source.version,
            "entry_point": e.registered.source.entry_point,
        }
        for e in experiment.components
    ]


def run_record(
    session: Session, wall_time_s: float, error: str | None, signal: str | None = None
) -> dict[str, Any]:
    """The content of ``run.json``."""
    extra: dict[str, Any] = {}
    for part in session.hook.hapticframe_run_metadata(session=session.view()):
        if part:
            extra.update(part)
    record: dict[str, Any] = {
        "status": session.status,
        "error": error,
        "experiment_file": str(session.experiment.file),
        "name": session.experiment.model.name,
        "seed": session.experiment.seed,
        "started_utc": session.started_utc,
        "wall_time_s": wall_time_s,
        "movements": len(session.movements),
        "versions": environment(),
        "plugins": plugin_records(session.experiment),
        "plugin_metadata": extra,
        "resolved_config": session.experiment.resolved_config(),
        # What `--set` changed of the file (the resolved config holds the values).
        "overrides": list(session.experiment.overrides),
        "details": dict(session.details),
    }
    if signal is not None:
        record["signal"] = signal
    return record


def save_outputs(session: Session, metrics: Mapping[str, Any]) -> None:
    """Write ``trace.npz`` and ``metrics.json`` into the run's directory, atomically."""
    with atomic_path(session.out_dir / "trace.npz") as temp:
        session.recorder.save(str(temp))
    write_json(session.out_dir / "metrics.json", metrics)


#: What a finished run of an earlier version (no ``files`` in its record) wrote at its
#: directory's top level, and ``--overwrite`` may therefore delete.
_LEGACY_SUFFIXES = frozenset({".png", ".npz", ".json", ".md", ".pt"})


# --- the --out directory ---------------------------------------------------------------------


def min_free_bytes() -> int:
    """The free space ``--out`` needs: ``HAPTICFRAME_MIN_FREE_MB`` or :data:`MIN_FREE_BYTES`."""
    text = os.environ.get(MIN_FREE_ENV, "").strip()
    if not text:
        return MIN_FREE_BYTES
    try:
        megabytes = float(text)
    except ValueError:
        raise UsageError(f"{MIN_FREE_ENV}={text!r} is not a number of megabytes") from None
    if not math.isfinite(megabytes) or megabytes < 0:
        raise UsageError(f"{MIN_FREE_ENV}={text!r} must be a finite number of megabytes >= 0")
    return int(megabytes * 1024 * 1024)


def _listing(names: list[str], limit: int = 5) -> str:
    shown = ", ".join(sorted(names)[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def _is_ours_by_name(name: str) -> bool:
    return name == STAGING or name.startswith(TEMP_PREFIX)


@dataclass
class OutputDir:
    """The ``--out`` directory of a run (``record = "run.json"``) or of a training run
    (``"train.json"``), checked and cleared by :meth:`prepare`.

    The life of a run's directory: :meth:`prepare` (checks; clears with ``--overwrite``),
    :meth:`begin` (``record`` says ``running``; the staging folder is made), the run
    writes into :attr:`staging`, :meth:`commit` (the staged files move in, listed first),
    then :meth:`finish` (the final record). :meth:`discard` undoes :meth:`begin` for a run
    that wrote nothing (it failed to build).
    """

    path: Path
    record: str = "run.json"
    command: str = "run"
    #: Folders :meth:`prepare` created (removed again by :meth:`discard`), innermost first.
    created: list[Path] = field(default_factory=list)
    #: The directory's lock, held from :meth:`prepare` until :meth:`release`.
    lock: DirectoryLock | None = None
    #: What each folder the command moved in holds (its files' paths inside it): the
    #: record lists it (``trees``), and ``--overwrite`` deletes those files by name.
    trees: dict[str, list[str]] = field(default_factory=dict)

    @property
    def staging(self) -> Path:
        """Where the run writes its files until :meth:`commit`."""
        return self.path / STAGING

    @property
    def record_path(self) -> Path:
        return self.path / self.record

    @classmethod
    def prepare(
        cls,
        path: str | Path,
        *,
        record: str = "run.json",
        command: str = "run",
        overwrite: bool = False,
        min_free: int | None = None,
        inputs: Sequence[str | Path] = (),
    ) -> OutputDir:
        """Check ``path`` before anything runs, create it, lock it for this process (see
        :mod:`hapticframe._lock`), and with ``overwrite`` clear the results hapticframe left
        there. The caller ends with :meth:`release` (or :meth:`discard`).

        ``inputs``: files the command reads; an input inside ``path`` is refused, so that
        clearing the directory never deletes what the command is about to read.

        Raises
        ------
        UsageError
            ``path`` lies below a regular file, is or holds one of ``inputs``, holds
            results (a finished or unfinished run, or files hapticframe did not write) that
            ``overwrite`` may not replace, or another process writes into it now
            (:class:`~hapticframe._lock.DirectoryBusy`) (exit status 2). Nothing is deleted
            then.
        OutputError
            ``path`` cannot be created or written, or has less than ``min_free`` bytes free
            (default :func:`min_free_bytes`) (exit status 1).
        """
        out = cls(Path(path), record, command)
        out._check_inputs(inputs)
        out._create()
        try:
            out.lock = lock_directory(out.path, command)
            out._probe(min_free_bytes() if min_free is None else min_free)
            out._clear(overwrite)
        except BaseException:
            out.release()
            out._remove_created()  # a refused --out is left as it was found
            raise
        return out

    def _check_inputs(self, inputs: Sequence[str | Path]) -> None:
        here = self.path.resolve()
        for given in inputs:
            if not Path(given).exists():
                continue  # nothing there to destroy (an experiment made in memory)
            source = Path(given).resolve()
            if source == here or here in source.parents:
                raise UsageError(
                    f"--out {self.path} is also where this {self.command} reads {given}: "
                    "clearing or writing it would destroy its own input; choose another --out")

    def release(self) -> None:
        """Let the directory's lock go (idempotent): another command may write here now."""
        if self.lock is not None:
            self.lock.release()

    def _create(self) -> None:
        missing = []
        for folder in (self.path, *self.path.parents):
            if folder.is_dir():
                break
            if folder.exists() or folder.is_symlink():
                raise UsageError(
                    f"--out {self.path}: {folder} is not a directory; choose a directory")
            missing.append(folder)
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except (NotADirectoryError, FileExistsError) as exc:
            raise UsageError(f"--out {self.path}: a part of the path is a file, not a "
                             f"directory ({exc.strerror}); choose a directory") from exc
        except OSError as exc:
            raise output_error(self.path, exc, "cannot create --out") from exc
        self.created = missing

    def _probe(self, min_free: int) -> None:
        try:
            atomic_write(self.path / f"{TEMP_PREFIX}{os.getpid()}-probe", b"probe").unlink()
        except OutputError as exc:
            raise OutputError(f"--out {self.path} is not writable: {exc}", self.path) from exc
        except OSError as exc:
            raise output_error(self.path, exc, "--out is not writable:") from exc
        try:
            free = shutil.disk_usage(self.path).free
        except OSError:  # a file system that does not say: nothing to check
            return
        if free < min_free:
            raise OutputError(
                f"--out {self.path} has {free / 2**20:.1f} MB free; a {self.command} needs at "
                f"least {min_free / 2**20:.1f} MB: free some space, choose another --out, or "
                f"lower the minimum ({MIN_FREE_ENV} or --min-free-mb)", self.path)

    def read_record(self) -> dict[str, Any] | None:
        """The directory's record (``run.json``), None when there is none; UsageError when
        it cannot be read (hapticframe writes it atomically: someone else wrote it)."""
        try:
            text = self.record_path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return None
        except (OSError, UnicodeDecodeError) as exc:
            raise UsageError(f"--out {self.path}: {self.record} cannot be read ({exc}); "
                             "choose another directory, or empty this one yourself") from exc
        try:
            record = json.loads(text)
        except ValueError:
            record = None
        if not isinstance(record, dict):
            raise UsageError(
                f"--out {self.path}: {self.record} is not a hapticframe record (not a JSON "
                "object); it may be from another program or an earlier version: choose "
                "another directory, or empty this one yourself")
        return record

    def _clear(self, overwrite: bool) -> None:
        entries = os.listdir(self.path)
        record = self.read_record()
        ours = {n for n in entries if _is_ours_by_name(n)}
        trees: dict[str, list[str]] = {}
        foreign: list[str] = []
        if record is not None:
            ours.add(self.record)
            listed = record.get("files")
            if isinstance(listed, list):
                named = {n for n in listed if isinstance(n, str) and n in entries
                         and _plain_name(n)}
                # A listed folder is ours only as far as the record says what it holds, and
                # it holds nothing else: never a tree hapticframe did not make.
                for name in sorted(named):
                    entry = self.path / name
                    if entry.is_dir() and not entry.is_symlink():
                        tree = _own_tree(entry, record.get("trees"), name)
                        if tree is None:
                            foreign.append(name + "/")
                            named.discard(name)
                        else:
                            trees[name] = tree
                ours |= named
            elif record.get("status") in FINISHED and "versions" in record:
                # A finished run of a version that did not list its files: what such runs
                # wrote, at the top level (figures, arrays, metrics), is theirs.
                ours |= {n for n in entries if _plain_name(n) and (self.path / n).is_file()
                         and Path(n).suffix in _LEGACY_SUFFIXES}
        # Hidden files (.DS_Store, .git) are no results: left alone, never deleted.
        unknown = [n for n in entries if n not in ours and not n.startswith(".")
                   and n + "/" not in foreign] + foreign
        status = record.get("status") if record is not None else None
        finished = status in FINISHED
        redo = "choose another directory, or pass --overwrite to clear it first"
        if record is None and (unknown or ours):
            what = (f"holds files but no {self.record} ({_listing(unknown)}): an unfinished "
                    f"{self.command} of an earlier version, or files of your own"
                    if unknown else f"holds an unfinished {self.command} (no {self.record})")
            if unknown or not overwrite:
                raise UsageError(f"--out {self.path} {what}; "
                                 + ("choose an empty directory, or empty it yourself"
                                    if unknown else redo))
        elif record is not None and not overwrite:
            if finished:
                raise UsageError(
                    f"--out {self.path} already holds a {self.command} ({self.record}, status "
                    f"{status}); {redo}")
            raise UsageError(
                f"--out {self.path} holds an unfinished {self.command} ({self.record} says "
                f"{status!r}: it was killed, or is running now); if none is running, pass "
                "--overwrite to clear it, or choose another directory")
        elif record is not None and unknown:
            raise UsageError(
                f"--out {self.path}: --overwrite would have to delete files hapticframe did "
                f"not write ({_listing(unknown)}; {self.record} does not list them): move them "
                "out of the directory, or choose another one")
        # Only now, every check passed: delete what hapticframe wrote, the record last, so
        # a clearing cut short still says what is left.
        for name in sorted(ours - {self.record}):
            if name in trees:
                self._delete_tree(self.path / name, trees[name])
            else:
                self._delete(self.path / name)
        if self.record in ours:
            self._delete(self.record_path)

    def _delete(self, path: Path) -> None:
        try:
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)  # only hapticframe's own names reach here (staging)
            else:
                path.unlink(missing_ok=True)
        except OSError as exc:
            raise output_error(path, exc, "--overwrite cannot delete") from exc

    def _delete_tree(self, folder: Path, files: list[str]) -> None:
        """Delete the files the record lists in ``folder`` by name, then its folders (each
        only once empty)."""
        try:
            for name in files:
                (folder / name).unlink(missing_ok=True)
            for sub in sorted((p for p in folder.rglob("*") if p.is_dir()),
                              key=lambda p: len(p.parts), reverse=True):
                sub.rmdir()
            folder.rmdir()
        except OSError as exc:
            raise output_error(folder, exc, "--overwrite cannot delete") from exc

    def begin(self, record: Mapping[str, Any]) -> None:
        """Write the record with ``status: running`` and make the staging folder."""
        write_json(self.record_path, {**record, "status": "running"})
        try:
            self.staging.mkdir(exist_ok=True)
        except OSError as exc:
            raise output_error(self.staging, exc, "cannot create") from exc

    def staged(self) -> list[str]:
        """The names the run has written so far (temporary files of cut writes left out)."""
        try:
            names = os.listdir(self.staging)
        except FileNotFoundError:
            return []
        return sorted(n for n in names if not n.startswith(TEMP_PREFIX))

    def commit(self, record: Mapping[str, Any]) -> list[str]:
        """Move the staged files into the directory; return their names.

        ``record`` (status still ``running``) is first rewritten with the names, so a kill
        while moving leaves a record that lists every file hapticframe wrote.
        """
        names = self.staged()
        self.trees = {name: _tree(self.staging / name) for name in names
                      if (self.staging / name).is_dir() and not (self.staging / name).is_symlink()}
        if names:
            write_json(self.record_path, {**record, "status": "running", "files": names,
                                          **({"trees": self.trees} if self.trees else {})})
        for name in names:
            source, target = self.staging / name, self.path / name
            try:
                if target.is_dir() and not target.is_symlink():
                    shutil.rmtree(target)  # only a hidden name can already be there
                os.replace(source, target)
            except OSError as exc:
                raise output_error(target, exc, "cannot move the result into place:") from exc
        self.drop_staging()
        return names

    def drop_staging(self) -> None:
        remove_quietly(self.staging)

    def finish(self, record: Mapping[str, Any], files: list[str]) -> None:
        """Write the final record (its ``status`` as given) listing ``files`` (and what each
        folder among them holds, ``trees``)."""
        trees = {n: t for n, t in self.trees.items() if n in files}
        write_json(self.record_path, {**record, "files": sorted(files),
                                      **({"trees": trees} if trees else {})})

    def discard(self) -> None:
        """Remove what :meth:`begin` wrote, and the folders :meth:`prepare` created: a
        command that failed before writing any result leaves nothing behind. Releases the
        lock."""
        self.drop_staging()
        remove_quietly(self.record_path)
        self.release()
        self._remove_created()

    def _remove_created(self) -> None:
        for folder in self.created:
            try:
                folder.rmdir()  # only when empty: never a file of anyone's
            except OSError:
                break


def _tree(folder: Path) -> list[str]:
    """The files below ``folder``, as paths relative to it (``/``-separated), sorted."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                  if not p.is_dir() or p.is_symlink())


def _own_tree(folder: Path, trees: Any, name: str) -> list[str] | None:
    """The files the record says ``folder`` holds, when it holds no other (else None)."""
    listed = trees.get(name) if isinstance(trees, dict) else None
    if not isinstance(listed, list) or not all(isinstance(p, str) for p in listed):
        return None
    allowed = set(listed)
    found = _tree(folder)
    if any(p not in allowed for p in found):
        return None
    if any(p.is_symlink() for p in folder.rglob("*")):
        return None
    return [p for p in found if p in allowed]


def _plain_name(name: str) -> bool:
    # A listed name is deleted only when it names an entry of the directory itself.
    return bool(name) and name not in (".", "..") and "/" not in name and "\\" not in name
