"""Entry-point discovery: broken plugins, conflicts, blocking and autoload control."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from hapticframe import Kind, PluginImportError, get_plugin_manager, make_plugin_manager
from hapticframe.cli._cli import main

PLUGIN = """
from hapticframe import SensorSpec, PluginConfig, hookimpl

class Config(PluginConfig):
    pass

@hookimpl
def hapticframe_sensors():
    yield SensorSpec("{name}", "A test sensor.", Config, "{module}:Missing")
"""


def make_dist(
    root: Path, dist: str, version: str, entry_points: dict[str, str], modules: dict[str, str]
) -> None:
    """A minimal installed distribution on ``root`` (a dist-info folder and its modules)."""
    info = root / f"{dist.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n")
    lines = "\n".join(f"{name} = {value}" for name, value in entry_points.items())
    (info / "entry_points.txt").write_text(f"[hapticframe]\n{lines}\n")
    for module, source in modules.items():
        (root / f"{module}.py").write_text(textwrap.dedent(source))


@pytest.fixture
def site(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delenv("HAPTICFRAME_DISABLE_PLUGIN_AUTOLOAD", raising=False)
    monkeypatch.delenv("HAPTICFRAME_BLOCKED_PLUGINS", raising=False)
    return tmp_path


def test_a_broken_entry_point_is_listed_and_does_not_stop_others(site):
    make_dist(site, "lab-good", "1.0", {"good": "hf_test_good"},
              {"hf_test_good": PLUGIN.format(name="lab-good-sensor", module="hf_test_good")})
    make_dist(site, "lab-bad", "2.0", {"bad": "hf_test_bad"},
              {"hf_test_bad": "raise ImportError('no driver')\n"})
    with pytest.warns(UserWarning, match="no driver"):
        pm = make_plugin_manager()
    registry = pm.registry
    assert "lab-good-sensor" in registry.plugins[Kind.SENSOR]
    broken = {b.name: b for b in registry.broken}
    assert "no driver" in broken["bad"].error and broken["bad"].source.distribution == "lab-bad"
    with pytest.raises(PluginImportError, match=r"lab-bad 2\.0"):
        make_plugin_manager(strict=True)


def test_conflicting_names_name_both_distributions(site):
    for dist, version in (("lab-one", "1.0"), ("lab-two", "3.1")):
        module = dist.replace("-", "_") + "_plugin"
        make_dist(site, dist, version, {dist: module},
                  {module: PLUGIN.format(name="shared-name", module=module)})
    registry = make_plugin_manager().registry
    [conflict] = registry.conflicts
    message = conflict.message()
    assert "lab-one 1.0" in message and "lab-two 3.1" in message and "'shared-name'" in message


def test_blocking_and_autoload_control(site, monkeypatch):
    make_dist(site, "lab-good", "1.0", {"good": "hf_test_good2"},
              {"hf_test_good2": PLUGIN.format(name="lab-blockable", module="hf_test_good2")})
    assert "lab-blockable" in make_plugin_manager().registry.plugins[Kind.SENSOR]
    monkeypatch.setenv("HAPTICFRAME_BLOCKED_PLUGINS", "good, other")
    assert "lab-blockable" not in make_plugin_manager().registry.plugins[Kind.SENSOR]
    monkeypatch.delenv("HAPTICFRAME_BLOCKED_PLUGINS")
    monkeypatch.setenv("HAPTICFRAME_DISABLE_PLUGIN_AUTOLOAD", "1")
    registry = make_plugin_manager().registry
    assert "lab-blockable" not in registry.plugins[Kind.SENSOR]
    # Plugins bundled with hapticframe itself still load, as pytest's builtins do.
    bundled = [r for r in registry if r.source.distribution == "hapticframe"]
    assert bundled


def test_malformed_registrations_are_broken_not_fatal(site):
    make_dist(site, "lab-odd", "1.0", {"odd": "hf_test_odd", "typo": "hf_test_typo"}, {
        "hf_test_odd": """
            from hapticframe import hookimpl
            @hookimpl
            def hapticframe_maps():
                yield "not a spec"
        """,
        "hf_test_typo": """
            from hapticframe import hookimpl
            @hookimpl
            def hapticframe_sensorz():
                return []
        """,
    })
    with pytest.warns(UserWarning, match="was skipped"):
        registry = make_plugin_manager().registry
    errors = " ".join(b.error for b in registry.broken)
    assert "yielded str, expected MapSpec" in errors
    assert "hapticframe_sensorz" in errors


def test_manager_is_built_once():
    assert get_plugin_manager() is get_plugin_manager()


def test_plugins_command_lists_kinds_and_broken(site, capsys):
    make_dist(site, "lab-bad", "2.0", {"bad": "hf_test_bad2"},
              {"hf_test_bad2": "raise RuntimeError('boom')\n"})
    get_plugin_manager.cache_clear()
    try:
        assert main(["plugins"]) == 0
        out = capsys.readouterr().out
        assert "KIND" in out and "broken   bad" in out and "boom" in out
        assert main(["plugins", "--strict"]) == 1
    finally:
        get_plugin_manager.cache_clear()


def test_error_hints_from_plugins_are_printed(site, capsys):
    make_dist(site, "lab-hints", "1.0", {"hints": "hf_test_hints"}, {"hf_test_hints": """
        from hapticframe import hookimpl
        @hookimpl
        def hapticframe_error_hints(error):
            return ["check the rig's cable"] if "no such file" in str(error) else []
    """})
    get_plugin_manager.cache_clear()
    try:
        assert main(["run", str(site / "missing.yaml"), "--out", str(site / "o")]) == 2
        err = capsys.readouterr().err
        assert "no such file" in err and "hint: check the rig's cable" in err
    finally:
        get_plugin_manager.cache_clear()


BENCH = """
from hapticframe import BenchSpec, hookimpl

@hookimpl
def hapticframe_benchmarks():
    yield BenchSpec("lab-suite", "A lab's suite.", "{module}:run")
    yield {extra}
"""


def test_a_benchmark_registered_twice_is_a_conflict_and_a_non_spec_is_broken(site, monkeypatch):
    from hapticframe._errors import PluginConflictError
    from hapticframe._registry import BENCHMARK
    from hapticframe.cli._bench import BenchOptions, run_bench

    for dist, version in (("lab-one", "1.0"), ("lab-two", "3.1")):
        module = dist.replace("-", "_") + "_bench"
        make_dist(site, dist, version, {dist: module},
                  {module: BENCH.format(module=module, extra='"not a spec"')})
    registry = make_plugin_manager().registry
    [conflict] = registry.conflicts
    assert (conflict.kind, conflict.name) == (BENCHMARK, "lab-suite")
    assert "lab-one 1.0" in conflict.message() and "lab-two 3.1" in conflict.message()
    assert sum("expected BenchSpec" in b.error for b in registry.broken) == 2
    # Running the conflicted name is an error that names both, as for any plugin.
    import hapticframe.cli._bench as bench

    monkeypatch.setattr(bench, "get_registry", lambda: registry)
    with pytest.raises(PluginConflictError, match=r"lab-one 1\.0"):
        run_bench("lab-suite", BenchOptions(out_dir=site / "bench"))
