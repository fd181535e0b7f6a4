"""The import graph of src/digiteyes follows DESIGN.md's data flow (issue 11):

* no import cycles between packages, nor between modules (a package's ``__init__``
  importing its own modules is not a cycle);
* no package imports a package further down the data flow (:data:`LAYERS`);
* no private module (``_name``) is imported from outside its own package.

Every ``import`` statement counts, including those inside functions (lazy imports).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import digiteyes

ROOT = Path(digiteyes.__file__).parent

LAYERS = (
    ("errors", "jsonfile", "version"),
    ("models",),
    ("kinematics",),
    ("camera", "filters"),
    ("io", "render"),
    ("synth",),
    ("features", "occlusion", "templates", "solvers"),
    ("smc", "detect"),
    ("trackers",),
    ("apps", "viz"),
    ("evaluate",),
    ("pipeline", "warmup", "track_job", "track_many", "mouse_job"),
    ("benchmarks",),
    ("commands",),
    ("cli", "_signals", "__init__", "__main__"),
)
"""DESIGN.md Sec. 1-2 from the top of the data flow down: a package may import packages
of its own layer or above, never below. ``io`` reads frames and writes logs (beside the
renderer: images in); ``synth`` writes sequences through it. ``filters`` smooths state
sequences (kinematics only) for ``io``'s track extras. ``track_job`` (one ``digiteyes
track`` run) and ``track_many`` (many, as Ray tasks) drive the run loop beside
``pipeline``, ``mouse_job`` the 3D mouse on footage from an automatic start;
``_signals`` serves ``cli`` alone."""
RANK = {name: i for i, layer in enumerate(LAYERS) for name in layer}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports() -> dict[str, set[str]]:
    """Module -> the digiteyes modules it imports (``from a import b`` counts ``a.b`` when
    that is a module, else ``a``)."""
    modules = {_module_name(p): p for p in ROOT.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(package.split(".")[:len(package.split(".")) - node.level + 1]
                                    + ([base] if base else []))
                found = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                         for a in node.names]
            else:
                continue
            targets |= {t for t in found if t.split(".")[0] == "digiteyes" and t != name}
        graph[name] = targets
    return graph


GRAPH = _imports()


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def test_every_package_has_a_layer():
    missing = sorted({_top(m) for m in GRAPH} - set(RANK))
    assert not missing, f"add these to LAYERS (DESIGN.md order): {missing}"


def test_no_package_imports_one_further_down_the_data_flow():
    wrong = sorted(f"{m} imports {t}" for m, targets in GRAPH.items() for t in targets
                   if _top(m) in RANK and _top(t) in RANK and RANK[_top(t)] > RANK[_top(m)])
    assert not wrong, "\n".join(wrong)


def test_no_private_module_imported_from_another_package():
    wrong = []
    for module, targets in GRAPH.items():
        own = module if (ROOT.parent / module.replace(".", "/") / "__init__.py").exists() \
            else module.rpartition(".")[0]
        for target in targets:
            parent, _, leaf = target.rpartition(".")
            if leaf.startswith("_") and not leaf.startswith("__") and parent != own:
                wrong.append(f"{module} imports {target}")
    assert not wrong, "\n".join(sorted(wrong))


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of ``graph`` (a list of nodes, first = last), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt):], nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_no_cycle_between_packages():
    packages: dict[str, set[str]] = {}
    for module, targets in GRAPH.items():
        packages.setdefault(_top(module), set()).update(
            _top(t) for t in targets if _top(t) != _top(module))
    assert _cycle(packages) is None, " -> ".join(_cycle(packages))


def test_no_cycle_between_modules():
    def is_own_init(module: str, target: str) -> bool:
        return module.startswith(target + ".")  # a module importing its package's API

    graph = {m: {t for t in targets if not is_own_init(m, t)} for m, targets in GRAPH.items()}
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


@pytest.mark.parametrize("graph, expected", [
    ({"a": {"b"}, "b": {"a"}}, ["a", "b", "a"]),
    ({"a": {"b"}, "b": set()}, None),
])
def test_cycle_finder(graph, expected):
    assert _cycle(graph) == expected
