"""The README's ``import`` and ``import-bag`` commands run, as written, on data that ships.

Every ``hapticframe import`` and ``hapticframe import-bag`` line of the README's shell blocks
is taken from the README itself and run from the repository root with its ``--out`` moved
to a temporary directory, so the README cannot drift from the command line or the data.
"""

from __future__ import annotations

import itertools
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from hapticframe.cli._cli import main
from hapticframe.record._recording import read_recording

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TRAINING = ROOT / "plugins" / "hapticframe_raking" / "data" / "training.npz"


def readme_commands(subcommand: str) -> list[list[str]]:
    """The README's shell-block lines that run ``hapticframe SUBCOMMAND``, as argument lists
    (comments dropped, the leading ``hapticframe`` removed)."""
    blocks = re.findall(r"```bash\n(.*?)```", README.read_text(), flags=re.DOTALL)
    commands = []
    for block in blocks:
        for line in block.splitlines():
            words = shlex.split(line, comments=True)
            if words[:2] == ["hapticframe", subcommand]:
                commands.append(words[1:])
    return commands


def with_out(words: list[str], out: Path) -> list[str]:
    """``words`` with the value of ``--out`` replaced by ``out``."""
    index = words.index("--out")
    return [*words[:index + 1], str(out), *words[index + 2:]]


def test_the_readme_shows_both_imports_on_shipped_data() -> None:
    bags, tables = readme_commands("import-bag"), readme_commands("import")
    assert bags and tables
    for words in bags + tables:
        # The input and every file named by an option exist in the repository.
        assert (ROOT / words[1]).exists(), words
        if "--layout" in words:
            assert (ROOT / words[words.index("--layout") + 1]).is_file(), words
    # No placeholder and no topic that no shipped bag holds (the old /ft_sensor/wrench).
    text = README.read_text()
    assert "/ft_sensor/wrench" not in text and "TABLES.xlsx" not in text


def test_the_readme_import_bag_commands_run(tmp_path: Path, monkeypatch) -> None:
    pytest.importorskip("rosbags")
    monkeypatch.chdir(ROOT)
    for number, words in enumerate(readme_commands("import-bag")):
        out = tmp_path / f"bag-{number}"
        assert main(with_out(words, out)) == 0, words
        recording = read_recording(out / "run.mcap")
        topics = [value.split("=", 1)[1] for key, value in itertools.pairwise(words)
                  if key == "--map"]
        assert topics
        for sensor in topics:
            samples = sum(len(d["timestamps_s"]) for _, d in recording[f"/sensor/{sensor}"])
            assert samples > 0, (words, sensor)


def test_the_readme_import_commands_run_and_give_the_shipped_values(tmp_path: Path,
                                                                      monkeypatch) -> None:
    pytest.importorskip("openpyxl")
    monkeypatch.chdir(ROOT)
    commands = readme_commands("import")
    with np.load(TRAINING, allow_pickle=False) as npz:
        training = {key: npz[key] for key in npz.files}
    names = [str(n) for n in training["import/trial_names"]]
    for number, words in enumerate(commands):
        out = tmp_path / f"tables-{number}"
        assert main(with_out(words, out)) == 0, words
        with np.load(out / "trace.npz", allow_pickle=False) as npz:
            trace = {key: npz[key] for key in npz.files}
        # The workbook holds the first steps of shipped training trials: the import gives
        # those trials' values back, step for step.
        starts = trace["import/trial_starts"]
        ends = [*starts[1:], trace["sensor/tactile/timestamps_s"].size]
        assert len(starts) == 2
        for name, start, end in zip(trace["import/trial_names"], starts, ends, strict=True):
            first = int(training["import/trial_starts"][names.index(str(name))])
            source = slice(first, first + int(end - start))
            for key in ("sensor/tactile/taxel_force", "sensor/tactile/distance_mm",
                        "sensor/tactile/direction_class", "sensor/tactile/depth_class",
                        "robot/tool/position_m"):
                np.testing.assert_array_equal(trace[key][start:end], training[key][source],
                                              err_msg=f"{key}, trial {name}")
