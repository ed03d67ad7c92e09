"""Writing what a run or a training run leaves behind: ``run.json``, ``metrics.json``,
``trace.npz`` and the JSON helpers ``hapticframe train`` shares.

``run.json`` records the status (``ok``, ``failed`` or ``interrupted`` with the signal),
the error, the seed, the versions of hapticframe, Python and every scientific dependency
that is installed, the git commit of the project when it is a git checkout, every
plugin's distribution and version, and the resolved config.
"""

from __future__ import annotations

import functools
import json
import math
import platform
import subprocess
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from ._config import Experiment
from ._session import Session
from ._version import __version__

__all__ = ["RunSummary", "environment", "git_commit", "run_record", "write_json"]

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
    """The metrics of a finished run (a dict), plus where they were written."""

    out_dir: Path


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def write_json(path: Path, data: Mapping[str, Any]) -> None:
    """Write ``data`` as sorted, indented JSON; NaN and infinities become null."""
    clean = json.loads(json.dumps(data, default=_json_default, allow_nan=True))
    text = json.dumps(_nan_to_none(clean), indent=2, sort_keys=True, allow_nan=False)
    path.write_text(text + "\n", encoding="utf-8")


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
        root = Path(__file__).resolve().parent.parent
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
        "details": dict(session.details),
    }
    if signal is not None:
        record["signal"] = signal
    return record


def save_outputs(session: Session, metrics: Mapping[str, Any]) -> None:
    """Write ``trace.npz`` and ``metrics.json`` into the run's directory."""
    session.recorder.save(str(session.out_dir / "trace.npz"))
    write_json(session.out_dir / "metrics.json", metrics)
