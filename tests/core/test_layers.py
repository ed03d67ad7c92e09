"""The core's packages import downward only, and no module imports itself back.

Layers, lowest first (docs/architecture.md, "Layers"):

- ``devices``: transports, framing, clocks, fault schedules (imports nothing else of ours);
- the kernel: kinds, spec records, registry and plugin manager, configuration, errors,
  scene, geometry, the public helpers (``plotting``, ``artifacts``, ...);
- ``run``: assembly, session, dataflow, loop, robots, safety, scoring, results, training;
- ``record`` and ``testing`` (peers): the recording and what reads it; the conformance kit;
- ``live`` and ``sweep`` (peers);
- ``cli``;
- the facades on top: ``hapticframe`` itself, ``hapticframe.recording``, ``__main__``.

Every import counts, type-only (``if TYPE_CHECKING:``) and function-local ones included: a
type-only import upward is still a dependency a reader must follow.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

import hapticframe

CORE = Path(hapticframe.__file__).parent

#: Rank of each layer; a module may import its own layer's modules and lower ranks only.
RANKS = {"devices": 0, "kernel": 1, "run": 2, "record": 3, "testing": 3, "live": 4,
         "sweep": 4, "cli": 5, "facade": 6}
#: Subpackages that are layers of their own; every other module is the kernel's.
PACKAGE_LAYERS = ("devices", "run", "record", "testing", "live", "sweep", "cli")
FACADES = ("hapticframe", "hapticframe.recording", "hapticframe.__main__")
#: Upward imports still to remove (each names the module pair); the list only shrinks.
KNOWN_UPWARD: set[tuple[str, str]] = set()


def module_name(path: Path, root: Path = CORE) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer_of(module: str) -> str:
    if module in FACADES:
        return "facade"
    second = module.split(".")[1]
    return second if second in PACKAGE_LAYERS else "kernel"


def import_graph(root: Path = CORE) -> dict[str, dict[str, int]]:
    """Module -> {imported module: first line}, for every import of one core module by another."""
    modules = {module_name(p, root): p for p in root.rglob("*.py")}
    graph: dict[str, dict[str, int]] = defaultdict(dict)
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - node.level + 1]
                    stem = ".".join(base + ([node.module] if node.module else []))
                else:
                    stem = node.module or ""
                # ``from pkg import mod`` is an import of the module ``pkg.mod`` when there
                # is one, else of ``pkg`` itself.
                named = [f"{stem}.{alias.name}" for alias in node.names]
                targets = [m for m in named if m in modules] or [stem]
            else:
                continue
            for target in targets:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                # A package's own __init__ runs before its modules: importing it is no edge.
                if target and target != name and not name.startswith(target + "."):
                    graph[name].setdefault(target, node.lineno)
    return graph


def upward_imports(graph: dict[str, dict[str, int]]) -> list[str]:
    found = []
    for source, targets in graph.items():
        for target, line in targets.items():
            a, b = layer_of(source), layer_of(target)
            if (source, target) in KNOWN_UPWARD:
                continue
            if RANKS[b] > RANKS[a] or (RANKS[b] == RANKS[a] and a != b):
                found.append(f"{source}:{line} ({a}) imports {target} ({b})")
    return sorted(found)


def cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0
    nodes = set(graph) | {t for targets in graph.values() for t in targets}
    for start in sorted(nodes):
        if start in index:
            continue
        work = [(start, iter(sorted(graph.get(start, {}))))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, {})))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_every_core_module_belongs_to_a_layer():
    for path in CORE.rglob("*.py"):
        assert layer_of(module_name(path)) in RANKS


def test_no_core_module_imports_a_layer_above_its_own():
    found = upward_imports(import_graph())
    assert not found, "imports against the layers:\n" + "\n".join(found)


def test_the_core_has_no_import_cycle():
    found = cycles(import_graph())
    assert not found, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in found)


def _write(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root / "hapticframe"


@pytest.mark.parametrize("form", [
    "from hapticframe.record._writer import Writer\n",
    "import typing\nif typing.TYPE_CHECKING:\n    from hapticframe.record import _writer\n",
    "def late():\n    from ..record._writer import Writer\n",
])
def test_the_checks_catch_an_upward_import_in_each_form(tmp_path, form):
    core = _write(tmp_path, {
        "hapticframe/__init__.py": "",
        "hapticframe/run/__init__.py": "",
        "hapticframe/run/_loop.py": form,
        "hapticframe/record/__init__.py": "",
        "hapticframe/record/_writer.py": "from hapticframe.run import _loop\nWriter = 1\n",
    })
    graph = import_graph(core)
    line = form.count("\n")
    assert upward_imports(graph) == [
        f"hapticframe.run._loop:{line} (run) imports hapticframe.record._writer (record)"
    ]
    assert cycles(graph) == [["hapticframe.record._writer", "hapticframe.run._loop"]]


def test_peers_may_not_import_each_other(tmp_path):
    core = _write(tmp_path, {
        "hapticframe/__init__.py": "",
        "hapticframe/live/__init__.py": "from hapticframe.sweep import x\n",
        "hapticframe/sweep/__init__.py": "",
        "hapticframe/sweep/x.py": "",
    })
    assert upward_imports(import_graph(core)) == [
        "hapticframe.live:1 (live) imports hapticframe.sweep.x (sweep)"
    ]
