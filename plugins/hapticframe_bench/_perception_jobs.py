"""Kept jobs of the perception bench: a full run resumes where an earlier one stopped.

Each finished job (one modality set and seed, six models) is written to ``job_dir`` as JSON
with a fingerprint of everything its result depends on (:func:`job_fingerprint`); a later
run with the same fingerprint reuses it instead of training again.
"""

from __future__ import annotations

import hashlib
import importlib
import json
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["job_fingerprint", "keep_job", "kept_job", "model_digest"]


def _key(modalities: Any) -> str:
    return "+".join(modalities)


def model_digest(directory: str | Path) -> str | None:
    """sha256 over a saved model's two files, or None when either is missing."""
    digest = hashlib.sha256()
    for name in ("model.json", "weights.pt"):
        path = Path(directory) / name
        if not path.is_file():
            return None
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _job_file(job_dir: Path, job: tuple[Any, ...]) -> Path:
    return job_dir / f"seed{job[0]}-{_key(job[1])}.json"


def kept_job(job_dir: Path | None, job: tuple[Any, ...],
             fingerprint: str) -> dict[str, Any] | None:
    """A job's result kept by an earlier run with the same fingerprint, else None."""
    if job_dir is None:
        return None
    path = _job_file(job_dir, job)
    try:
        kept = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(kept, dict) or kept.get("fingerprint") != fingerprint:
        return None
    result = kept.get("result")
    if not isinstance(result, dict):
        return None
    save_dir = job[5]
    if "model_sha256" in result and (save_dir is None
                                     or model_digest(save_dir) != result["model_sha256"]):
        return None  # the job that saves the model reruns unless its saved model is intact
    result["modalities"] = tuple(result["modalities"])
    return result


def keep_job(job_dir: Path | None, job: tuple[Any, ...], fingerprint: str,
             result: dict[str, Any]) -> None:
    """Write a finished job's result with its fingerprint (nothing when ``job_dir`` is None)."""
    if job_dir is None:
        return
    job_dir.mkdir(parents=True, exist_ok=True)
    path = _job_file(job_dir, job)
    partial = path.with_suffix(".part")
    partial.write_text(json.dumps({"fingerprint": fingerprint, "result": result},
                                  allow_nan=False) + "\n", encoding="utf-8")
    partial.replace(path)  # atomic: an interrupted write never leaves a half file behind


#: Packages whose code decides a job's result; an edit to any of them retires kept jobs.
_FINGERPRINT_PACKAGES = ("hapticframe", "hapticframe_bench", "hapticframe_biotac",
                         "hapticframe_tactile_features", "hapticframe_sfrnn")


def job_fingerprint(plan: Any, seed: int, data: Any) -> str:
    """A digest of what a job's result depends on.

    The plan, the seed, the library versions, the source files of the packages that make
    the data and the models, and each trial's split, medium and labels. The features
    themselves are left out: they follow from those, and a float digest could change with
    the BLAS threads of the coder's pass.
    """
    digest = hashlib.sha256()
    versions: dict[str, str | None] = {}
    for name in ("numpy", "scipy", "scikit-learn", "torch"):
        try:
            versions[name] = version(name)
        except PackageNotFoundError:
            versions[name] = None
    digest.update(json.dumps({"plan": plan.as_dict(), "seed": int(seed), "versions": versions},
                             sort_keys=True, default=str).encode())
    for package in _FINGERPRINT_PACKAGES:
        root = Path(importlib.import_module(package).__file__ or "").parent
        for source in sorted(root.rglob("*.py")):
            digest.update(source.relative_to(root).as_posix().encode())
            digest.update(source.read_bytes())
    for trial in data.trials:
        digest.update(f"{trial.index}:{trial.split}:{trial.medium}:{len(trial)}".encode())
        digest.update(np.ascontiguousarray(trial.labels, dtype=np.int64).tobytes())
    return digest.hexdigest()
