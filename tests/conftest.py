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


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--hardware",
        action="store_true",
        default=False,
        help="run the tests marked 'hardware' against real devices (their ports come from "
        "environment variables such as HAPTICFRAME_FT300_PORT)",
    )


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if config.getoption("--hardware"):
        return
    skip = pytest.mark.skip(reason="needs a real device: run with --hardware")
    for item in items:
        if item.get_closest_marker("hardware") is not None:
            item.add_marker(skip)
