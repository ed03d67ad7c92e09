"""Corrupt saved jamming thresholds: each is a ValueError naming the file (issue 16 §2)."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hapticframe.kinds import BuildContext
from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig


def make(model_dir: Path | None = None) -> ForceRateJammingClassifier:
    config = ForceRateJammingConfig(model_dir=str(model_dir) if model_dir else None)
    return ForceRateJammingClassifier(config, BuildContext(id="jam", rng=np.random.default_rng(0)))


@pytest.fixture
def model_dir(tmp_path: Path) -> Path:
    """Thresholds saved by save() (train-free: the configured ones)."""
    make().save(tmp_path / "model")
    return tmp_path / "model"


def refused(model_dir: Path, match: str) -> str:
    with pytest.raises(ValueError, match=match) as info:
        make(model_dir)
    message = str(info.value)
    assert "thresholds.json" in message and len(message) < 1000
    return message


def edit(model_dir: Path, change: Callable[[dict[str, Any]], Any]) -> None:
    record = json.loads((model_dir / "thresholds.json").read_text())
    change(record)
    (model_dir / "thresholds.json").write_text(json.dumps(record))


def test_round_trip_and_integer_json_numbers(model_dir: Path) -> None:
    assert make(model_dir).thresholds == make().thresholds
    edit(model_dir, lambda r: r["thresholds"].update(jamming_force_n=7))
    assert make(model_dir).config.jamming_force_n == 7.0


def test_truncated_and_empty(model_dir: Path) -> None:
    text = (model_dir / "thresholds.json").read_text()
    (model_dir / "thresholds.json").write_text(text[: len(text) // 2])
    refused(model_dir, r"no jamming thresholds .* is not valid JSON .* truncated")
    (model_dir / "thresholds.json").write_text("")
    refused(model_dir, r"thresholds\.json is empty")


def test_nan_and_infinite_thresholds(model_dir: Path) -> None:
    text = (model_dir / "thresholds.json").read_text()
    for literal in ("NaN", "Infinity", "1e400"):
        record = json.loads(text)
        record["thresholds"]["contact_force_n"] = "@"
        (model_dir / "thresholds.json").write_text(json.dumps(record).replace('"@"', literal))
        refused(model_dir, "NaN|Infinity|contact_force_n")


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda r: r.update(filter=[3.0, 2, 100.0]), r"bad thresholds: .*filter"),
        (lambda r: r.update(thresholds=[6.0, 27.0, 30.0, 70.0]), "bad thresholds: .*thresholds"),
        (lambda r: r["thresholds"].update(jamming_force_n="6"), "thresholds.jamming_force_n"),
        (lambda r: r["thresholds"].update(jamming_force_n=True), "thresholds.jamming_force_n"),
        (lambda r: r["thresholds"].update(contact_force_n=1e300), "thresholds.contact_force_n"),
        (lambda r: r["filter"].update(filter_order=2.5), "filter.filter_order"),
        (lambda r: r["filter"].update(filter_order=1000), "filter.filter_order"),
        (lambda r: r["filter"].update(cutoff_hz=-3.0), "filter.cutoff_hz"),
        (lambda r: r.update(training_report="none"), "training_report"),
        (lambda r: r.update(force_channel=["force_n"]), "force_channel"),
        (lambda r: r.update(extra={}), "extra"),
        (lambda r: r["thresholds"].pop("contact_rate_n_per_s"), "contact_rate_n_per_s"),
    ],
)
def test_wrong_types_and_values(
    model_dir: Path, change: Callable[[dict[str, Any]], Any], match: str
) -> None:
    edit(model_dir, change)
    refused(model_dir, match)


def test_not_an_object_and_repeated_keys(model_dir: Path) -> None:
    (model_dir / "thresholds.json").write_text("[1, 2]")
    refused(model_dir, "holds a JSON list, not an object")
    (model_dir / "thresholds.json").write_text('{"format": 1, "format": 2}')
    refused(model_dir, "repeats the key 'format'")
    (model_dir / "thresholds.json").write_text("[" * 100_000)
    refused(model_dir, "thresholds.json")


def test_a_fifo_and_a_huge_file_are_not_read(model_dir: Path) -> None:
    (model_dir / "thresholds.json").unlink()
    os.mkfifo(model_dir / "thresholds.json")
    refused(model_dir, "is not a regular file")
    (model_dir / "thresholds.json").unlink()
    (model_dir / "thresholds.json").write_text(" " * (5 << 20))
    refused(model_dir, r"holds \d+ bytes, more than")


def test_hapticframe_run_with_a_corrupt_model_dir_exits_2_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hapticframe.cli._cli import main

    examples = Path(__file__).resolve().parents[2] / "examples"
    text = (examples / "search-ellipse.yaml").read_text()
    model_dir = tmp_path / "trained"
    model_dir.mkdir()
    (model_dir / "thresholds.json").write_text('{"format": "hapticframe-force-rate-jamming", '
                                               '"format_version": 1, "thresholds": [1, 2]}')
    text = text.replace("    inputs: [wrist]\n",
                        f"    inputs: [wrist]\n    config: {{model_dir: {model_dir}}}\n", 1)
    assert "model_dir" in text
    experiment = tmp_path / "experiment.yaml"
    experiment.write_text(text)
    assert main(["run", str(experiment), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "internal error" not in err and "thresholds.json" in err and "thresholds" in err
    assert "instance of" not in err
