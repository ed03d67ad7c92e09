"""Plugin validators: checks across fields and components that ``validate`` runs, located."""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Iterator
from pathlib import Path

import pytest

from hapticframe import ExperimentError, Finding, ValidationContext, validate_file

PLUGIN = textwrap.dedent('''
    from hapticframe import PluginConfig, RobotSpec, Finding, hookimpl

    class Config(PluginConfig):
        speed_m_per_s: float = 0.05
        limit_m_per_s: float = 0.1

    def check(config, context):
        if config.speed_m_per_s > config.limit_m_per_s:
            yield Finding(f"speed {config.speed_m_per_s} m/s exceeds the limit "
                          f"{config.limit_m_per_s} m/s", field="speed_m_per_s")
        if config.speed_m_per_s > 0.5 * config.limit_m_per_s:
            yield Finding("over half the limit", severity="warning")
        assert context.id == "arm" and context.run is not None
        assert context.scene.region.x_max_m == 0.75

    @hookimpl
    def hapticframe_robots():
        yield RobotSpec(name="checked", summary="A robot with a validator.", config=Config,
                        factory="validated_plugin:Robot", validator="validated_plugin:check")
''')


def _experiment(tmp_path: Path, speed: float) -> Path:
    path = tmp_path / "exp.yaml"
    path.write_text(textwrap.dedent(f"""\
        schema_version: 1
        name: checked
        seed: 1
        scene:
          region: {{x_min_m: 0.0, x_max_m: 0.75, y_min_m: 0.0, y_max_m: 0.5}}
        robots:
          - id: arm
            type: checked
            config:
              speed_m_per_s: {speed}
        planners:
          - id: planner
            type: coverage
        """), encoding="utf-8")
    return path


@pytest.fixture
def plugin_module(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    (tmp_path / "validated_plugin.py").write_text(PLUGIN, encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield "validated_plugin"
    sys.modules.pop("validated_plugin", None)


def test_a_validator_error_is_located_at_its_field(tmp_path: Path, plugin_module: str) -> None:
    with pytest.raises(ExperimentError) as caught:
        validate_file(_experiment(tmp_path, 0.2), plugin_modules=[plugin_module])
    (issue,) = caught.value.issues
    assert issue.path == "robots[0].config.speed_m_per_s"
    assert issue.line == 10 and "exceeds the limit" in issue.message


def test_a_validator_warning_leaves_the_file_valid(tmp_path: Path, plugin_module: str) -> None:
    experiment = validate_file(_experiment(tmp_path, 0.08), plugin_modules=[plugin_module])
    (warning,) = experiment.warnings
    assert warning.path == "robots[0]" and "half the limit" in warning.message
    assert not validate_file(_experiment(tmp_path, 0.02),
                             plugin_modules=[plugin_module]).warnings


def test_findings_are_checked() -> None:
    with pytest.raises(ValueError, match="severity"):
        Finding("x", severity="fatal")  # type: ignore[arg-type]
    assert ValidationContext("a", {}, {}, None, None).inputs == {}
