"""Shared fixtures for the core's tests."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

SUPPORT = Path(__file__).parent / "support"
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def lab_dir(tmp_path: Path) -> Path:
    """A directory holding the lab-local test plugin and its open-loop experiment."""
    for name in ("labplugin.py", "lab-open-loop.yaml"):
        shutil.copy(SUPPORT / name, tmp_path / name)
    return tmp_path
