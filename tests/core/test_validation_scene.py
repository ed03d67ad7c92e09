"""Issue 16 §1: a scene `validate` accepts is one a run survives (finite, physical, apart).

Each mutant of a README example is refused by ``hapticframe validate`` and ``hapticframe
run`` with exit 2, located at the field, before anything is written.
"""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import pytest
import yaml

from hapticframe.cli._cli import main

ROOT = Path(__file__).resolve().parents[2]


def _example(name: str) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load((ROOT / "examples" / name).read_text())
    return data


def _write(tmp_path: Path, data: dict[str, Any]) -> Path:
    path = tmp_path / "mutant.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def refused(tmp_path: Path, data: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> str:
    """Validate and run ``data``: both exit 2 and write nothing; the error text."""
    path = _write(tmp_path, data)
    assert main(["validate", str(path)]) == 2
    text = capsys.readouterr().err
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out), "--quiet"]) == 2
    assert not out.exists()
    assert "internal error" not in text
    return text


def _ellipse() -> dict[str, Any]:
    return _example("search-ellipse.yaml")


def _circle() -> dict[str, Any]:
    return _example("search-circle-baseline.yaml")


def _set(data: dict[str, Any], path: tuple[Any, ...], value: Any) -> dict[str, Any]:
    data = copy.deepcopy(data)
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return data


INF, NAN = float("inf"), float("nan")
OBJ = ("scene", "objects", 0)

CASES = [
    ("huge centre", _ellipse, (*OBJ, "center_m"), [1.0e308, 0.21], "scene.objects[0].center_m"),
    ("NaN centre", _ellipse, (*OBJ, "center_m"), [NAN, 0.21], "scene.objects[0].center_m"),
    ("inf centre", _ellipse, (*OBJ, "center_m"), [0.4, INF], "scene.objects[0].center_m"),
    ("-inf centre", _ellipse, (*OBJ, "center_m"), [-INF, 0.2], "scene.objects[0].center_m"),
    ("inf radius", _circle, (*OBJ, "radius_m"), INF, "scene.objects[0].radius_m"),
    ("zero radius", _circle, (*OBJ, "radius_m"), 0.0, "scene.objects[0].radius_m"),
    ("NaN orientation", _ellipse, (*OBJ, "orientation_deg"), NAN,
     "scene.objects[0].orientation_deg"),
    ("huge semi-axes", _ellipse, (*OBJ, "semi_axes_m"), [1e308, 0.025],
     "scene.objects[0].semi_axes_m"),
    ("outside the region", _ellipse, (*OBJ, "center_m"), [0.74, 0.21],
     "scene.objects[0].center_m"),
    ("far outside", _circle, (*OBJ, "center_m"), [5.0, -3.0], "scene.objects[0].center_m"),
    ("larger than the region", _circle, (*OBJ, "radius_m"), 0.3, "scene.objects[0].radius_m"),
    ("huge region", _ellipse, ("scene", "region", "x_max_m"), 1e308, "scene.region.x_max_m"),
    ("inf region", _ellipse, ("scene", "region", "y_min_m"), -INF, "scene.region.y_min_m"),
    ("100 km region", _ellipse, ("scene", "region", "x_max_m"), 999.0, "scene.region"),
    ("inverted region", _ellipse, ("scene", "region", "x_max_m"), -0.5, "scene.region"),
    ("inf density", _ellipse, ("scene", "material", "bulk_density_kg_per_m3"), INF,
     "scene.material.bulk_density_kg_per_m3"),
    ("NUL in the material's name", _ellipse, ("scene", "material", "name"), "sand\x00",
     "scene.material.name"),
]


@pytest.mark.parametrize(("example", "where", "value", "located"),
                         [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_an_impossible_scene_is_refused_at_validate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], example: Any, where: tuple[Any, ...],
    value: Any, located: str,
) -> None:
    text = refused(tmp_path, _set(example(), where, value), capsys)
    assert f": {located}" in text, text
    assert "mutant.yaml:" in text  # a line number follows the file


def test_overlapping_objects_are_refused_at_the_second(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _ellipse()
    data["scene"]["objects"].append({"shape": "circle", "center_m": [0.45, 0.22],
                                     "radius_m": 0.03})
    text = refused(tmp_path, data, capsys)
    assert "scene.objects[1].center_m" in text and "overlaps objects[0]" in text


def test_objects_apart_are_accepted(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _ellipse()
    data["scene"]["objects"].append({"shape": "circle", "center_m": [0.15, 0.15],
                                     "radius_m": 0.04})
    data["scene"]["objects"].append({"shape": "polygon", "center_m": [0.6, 0.4],
                                     "vertices_m": [[0, 0], [0.05, 0], [0, 0.05]]})
    assert main(["validate", str(_write(tmp_path, data))]) == 0


def test_a_flat_polygon_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _set(_ellipse(), ("scene", "objects", 0),
                {"shape": "polygon", "center_m": [0.4, 0.2],
                 "vertices_m": [[0, 0], [0.05, 0], [0.1, 0]]})
    text = refused(tmp_path, data, capsys)
    assert "scene.objects[0]" in text and "area" in text


def test_a_region_written_in_centimetres_is_refused_with_that_question(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The README's 75 x 50 cm region, its numbers written as if the fields took centimetres.
    data = _ellipse()
    data["scene"]["region"] = {"x_min_m": 0.0, "x_max_m": 75.0, "y_min_m": 0.0, "y_max_m": 50.0}
    data["scene"]["objects"] = [{"shape": "ellipse", "center_m": [42.0, 21.0],
                                 "semi_axes_m": [4.5, 2.5], "orientation_deg": 35}]
    text = refused(tmp_path, data, capsys)
    path = tmp_path / "mutant.yaml"
    line = next(number for number, row in enumerate(path.read_text().splitlines(), 1)
                if row.strip() == "region:")
    assert f"{path}:{line}: scene.region: the region is 75 m along x" in text
    assert "did you mean centimetres?" in text and "0.75 m" in text
    # One side too long is enough, and the limit itself is a legal side.
    long_y = _set(_ellipse(), ("scene", "region"),
                  {"x_min_m": 0.0, "x_max_m": 0.75, "y_min_m": 0.0, "y_max_m": 20.5})
    assert "20.5 m along y" in refused(tmp_path, long_y, capsys)
    widest = _set(_ellipse(), ("scene", "region"),
                  {"x_min_m": -10.0, "x_max_m": 10.0, "y_min_m": 0.0, "y_max_m": 0.5})
    widest["run"]["figures"] = False
    assert main(["validate", str(_write(tmp_path, widest))]) == 0


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "tests" / "data" / "bhm")
                                        .glob("*.yaml")))
def test_the_bench_regions_up_to_10_by_10_m_stay_valid(name: str) -> None:
    assert main(["validate", str(ROOT / "tests" / "data" / "bhm" / name)]) == 0
