"""Shared fixtures for the core's tests."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

SUPPORT = Path(__file__).parent / "support"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def lab_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A directory holding the lab-local test plugin and its open-loop experiment; also the
    working directory, where ``--plugin-module labplugin`` finds the module."""
    for name in ("labplugin.py", "lab-open-loop.yaml"):
        shutil.copy(SUPPORT / name, tmp_path / name)
    monkeypatch.chdir(tmp_path)
    return tmp_path
