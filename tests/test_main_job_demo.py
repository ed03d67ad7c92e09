"""The README's main-job line is what ``make demo`` runs, and it runs with only the demo's
extras installed: the core's dependencies and ``DEMO_EXTRAS`` (matplotlib), nothing else.

The run is made in a subprocess in which every module of a distribution that ``make demo``
would not install is refused on import, as it would be missing there; the files the README
lists for the main job must then all be written.
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MAKEFILE = ROOT / "Makefile"
#: What the README says the main job writes.
FILES = {"metrics.json", "trace.npz", "ground_truth.npz", "run.mcap", "run.json",
         "logodds_phase1.png", "logodds_phase2.png", "bhm_mean.png", "bhm_std.png",
         "outline.png", "forces.png", "paths.png"}

BLOCKER = """
import importlib.abc, sys
FORBIDDEN = set(sys.argv[1].split(","))
class Missing(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.partition(".")[0] in FORBIDDEN:
            raise ModuleNotFoundError(f"No module named {name!r} (not in make demo)", name=name)
        return None
sys.meta_path.insert(0, Missing())
from hapticframe.cli._cli import main
raise SystemExit(main(sys.argv[2:]))
"""


def readme_main_job() -> list[str]:
    """The first command of the README's main-job section."""
    section = README.read_text().split("## The main job", 1)[1]
    block = re.search(r"```bash\n(.*?)```", section, flags=re.DOTALL)
    assert block is not None
    return shlex.split(block.group(1).splitlines()[0], comments=True)


def makefile_demo() -> tuple[list[str], list[str]]:
    """``make demo``'s command (``$(BIN)`` as its default ``.venv/bin``) and its extras."""
    text = MAKEFILE.read_text()
    extras = re.search(r"^DEMO_EXTRAS \?= *(\S+)", text, flags=re.MULTILINE)
    recipe = re.search(r"^demo: .*\n\t(.+)$", text, flags=re.MULTILINE)
    assert extras is not None and recipe is not None
    command = recipe.group(1).replace("$(BIN)", ".venv/bin")
    return shlex.split(command), extras.group(1).split(",")


def demo_distributions(extras: list[str]) -> set[str]:
    """hapticframe and every distribution its core and ``extras`` need, transitively."""
    wanted, seen = [("hapticframe", frozenset(extras))], set()
    while wanted:
        name, with_extras = wanted.pop()
        key = canonicalize_name(name)
        if key in seen:
            continue
        seen.add(key)
        for text in metadata.requires(name) or ():
            requirement = Requirement(text)
            environments = [{"extra": e} for e in with_extras] or [{"extra": ""}]
            if requirement.marker is None or any(requirement.marker.evaluate(env)
                                                 for env in environments):
                if canonicalize_name(requirement.name) == "hapticframe":
                    wanted.append(("hapticframe", frozenset(requirement.extras)))
                    seen.discard("hapticframe")
                else:
                    wanted.append((requirement.name, frozenset(requirement.extras)))
    return seen


def test_the_readme_main_job_is_what_make_demo_runs() -> None:
    command, _ = makefile_demo()
    assert readme_main_job() == command


def test_the_main_job_runs_with_only_the_demo_extras(tmp_path: Path) -> None:
    command, extras = makefile_demo()
    allowed = demo_distributions(extras)
    assert {"numpy", "matplotlib", "pydantic"} <= allowed and "torch" not in allowed
    forbidden = sorted(
        module for module, dists in metadata.packages_distributions().items()
        if module.isidentifier()
        and not {canonicalize_name(d) for d in dists} & allowed)
    assert "sklearn" in forbidden or "torch" in forbidden or "aiohttp" in forbidden
    args = command[1:]
    assert args[:1] == ["run"] and "--out" in args
    out = tmp_path / "demo"
    args[args.index("--out") + 1] = str(out)
    done = subprocess.run([sys.executable, "-c", BLOCKER, ",".join(forbidden), *args],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]
    assert FILES <= {p.name for p in out.iterdir()}
    metrics = json.loads((out / "metrics.json").read_text())
    # The README: with seed 7 it finds the ellipse in 5 movements, 1.3 cm from its centroid.
    stated = re.search(r"With seed 7 it finds\s+the ellipse in (\d+) movements, ([\d.]+) cm",
                       README.read_text())
    assert stated is not None
    assert metrics["object_found"] is True
    assert metrics["movements"] == int(stated.group(1))
    assert round(100 * metrics["centroid_error_m"], 1) == float(stated.group(2))


def test_the_blocker_refuses_what_make_demo_lacks() -> None:
    # The check above can fail: a module outside the demo's distributions is refused.
    pytest.importorskip("rosbags")
    done = subprocess.run([sys.executable, "-c", BLOCKER, "rosbags", "plugins"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0
    code = BLOCKER.replace("from hapticframe.cli._cli import main\n"
                           "raise SystemExit(main(sys.argv[2:]))\n", "import rosbags\n")
    done = subprocess.run([sys.executable, "-c", code, "rosbags"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode != 0 and "not in make demo" in done.stderr
