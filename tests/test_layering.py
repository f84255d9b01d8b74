"""The package map keeps its layers (issue 10, design.md "Layers"), read from the source alone.

Every module under ``brush_env/`` is parsed (``ast``, nothing is imported or executed) and each
``import`` / ``from ... import`` is resolved to a module name (relative imports included,
function-level imports included: a lazy upward import is still an upward import).  Rules:

* ``brush_env.engine`` (dynamics) imports none of the layers beside or above it: motion,
  experiments (and the old single-module ``experiment``), bench, validation, envs, cli, agents,
  nor gymnasium / torch / matplotlib / stable_baselines3.
* ``brush_env.motion`` (robot trajectories) imports none of those either (except the engine).
* ``brush_env.geometry`` (tooth crowns, mesh files, SDF baking) sits beside the engine: the engine
  may import it; it imports none of the layers above the engine, nor ``brush_env.coverage``, nor
  gymnasium / torch / matplotlib.
* ``brush_env.coverage`` (what the tips cleaned; envs and experiments use it) imports nothing
  above the engine and geometry, and the engine does not import it.
* ``brush_env.envs`` imports no agents and nothing of the rooms above it (cli, bench,
  experiments, validation).
* no module of ``brush_env`` imports ``agents`` (agents sit on top);
* the graph of imports among ``brush_env`` modules has no cycle, function-level imports included
  (a lazy import is the usual way to hide a cycle, not to remove it).

The rules name packages that may not exist yet (``motion/``, ``experiments/``, ``bench/``,
``validation/`` are being created): a rule about a missing package checks nothing today and
starts checking as soon as the package appears.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG_DIR = Path(__file__).resolve().parents[1] / "brush_env"

ABOVE_ENGINE = (
    "brush_env.coverage",
    "brush_env.motion",
    "brush_env.experiments",
    "brush_env.experiment",
    "brush_env.bench",
    "brush_env.validation",
    "brush_env.envs",
    "brush_env.cli",
    "agents",
)
NO_ML_OR_PLOTS = ("gymnasium", "torch", "matplotlib", "stable_baselines3")

#: layer prefix -> prefixes its modules must not import
RULES = {
    "brush_env.engine": ABOVE_ENGINE + NO_ML_OR_PLOTS,
    "brush_env.motion": tuple(p for p in ABOVE_ENGINE if p != "brush_env.motion") + NO_ML_OR_PLOTS,
    "brush_env.geometry": ABOVE_ENGINE + NO_ML_OR_PLOTS,
    "brush_env.coverage": tuple(p for p in ABOVE_ENGINE if p != "brush_env.coverage")
    + NO_ML_OR_PLOTS,
    "brush_env.envs": (
        "agents",
        "brush_env.cli",
        "brush_env.bench",
        "brush_env.experiments",
        "brush_env.experiment",
        "brush_env.validation",
    ),
    "brush_env": ("agents",),
}


def _within(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def module_name(path: Path, root: Path = PKG_DIR) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def find_modules(root: Path = PKG_DIR) -> dict[str, Path]:
    return {module_name(p, root): p for p in sorted(root.rglob("*.py"))}


def _function_level(tree: ast.AST) -> set[int]:
    """ids of import nodes inside a function body (executed on call, not on import)."""
    inner = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            inner.update(
                id(n) for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))
            )
    return inner


def imports_of(
    source: str, modname: str, is_package: bool, known: set[str]
) -> list[tuple[str, int, bool]]:
    """(imported module, line, at module level) for every import statement of ``source``.

    ``from X import y`` counts as importing ``X.y`` when that is a known module, else ``X``."""
    tree = ast.parse(source)
    inner = _function_level(tree)
    package = modname if is_package else modname.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        top = id(node) not in inner
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno, top) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module
            for a in node.names:
                sub = f"{target}.{a.name}"
                out.append((sub if sub in known else target, node.lineno, top))
    return out


def import_graph(root: Path = PKG_DIR):
    mods = find_modules(root)
    known = set(mods)
    return {
        m: imports_of(p.read_text(), m, p.name == "__init__.py", known) for m, p in mods.items()
    }


def layering_violations(graph) -> list[str]:
    bad = []
    for mod, imps in graph.items():
        for layer, banned in RULES.items():
            if not _within(mod, layer):
                continue
            for name, line, _ in imps:
                hit = next((b for b in banned if _within(name, b)), None)
                if hit is not None:
                    bad.append(f"{mod}:{line} imports {name} ({layer} must not import {hit})")
    return bad


def import_cycles(graph) -> list[list[str]]:
    """Strongly connected components (size > 1, or a self-import) of the import graph."""
    edges = {m: sorted({n for n, _, _ in imps if n in graph}) for m, imps in graph.items()}
    index, low, stack, on, sccs = {}, {}, [], set(), []

    def visit(v):  # Tarjan
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1 or v in edges[v]:
                sccs.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return sccs


# ---------------------------------------------------------------- the checks on brush_env
def test_the_walk_sees_the_package():
    graph = import_graph()
    assert {
        "brush_env",
        "brush_env.engine",
        "brush_env.engine.simulator",
        "brush_env.envs.flat_plate",
    } <= set(graph)
    # the resolver turns relative imports into module names (one known edge of each kind)
    sim = {n for n, _, _ in graph["brush_env.engine.simulator"]}
    assert "brush_env.engine.step" in sim  # from . import step as itg
    assert "brush_env.engine.rotation" in sim  # from .rotation import pose_ok


def test_the_engine_may_use_geometry_and_geometry_stays_below_the_rooms():
    graph = import_graph()
    scene = {n for n, _, _ in graph["brush_env.engine.scene"]}
    assert "brush_env.geometry.sdf_bake" in scene  # the engine imports geometry (allowed edge)
    assert "brush_env.geometry" not in RULES["brush_env.engine"]
    for room in ("brush_env.envs", "brush_env.experiments", "brush_env.coverage"):
        assert room in RULES["brush_env.geometry"]


def test_layers_import_nothing_from_above():
    assert layering_violations(import_graph()) == []


def test_no_circular_imports():
    assert import_cycles(import_graph()) == []


# ---------------------------------------------------------------- the checker can fail
@pytest.fixture
def fake_tree(tmp_path):
    """A throw-away ``brush_env`` with one upward import, one lazy one and a cycle."""
    files = {
        "__init__.py": "",
        "engine/__init__.py": "from .simulator import Simulator\n",
        "engine/simulator.py": (
            "from ..motion import trajectory\ndef f():\n    import agents.train\n"
        ),
        "engine/a.py": "from . import b\n",
        "engine/b.py": "def g():\n    import brush_env.engine.a\n",
        "motion/__init__.py": "",
        "motion/trajectory.py": "from brush_env.engine.a import x\n",
        "envs/__init__.py": "from agents import reference\n",
    }
    for rel, text in files.items():
        p = tmp_path / "brush_env" / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return tmp_path / "brush_env"


def test_checker_flags_upward_lazy_and_circular_imports(fake_tree):
    graph = import_graph(fake_tree)
    bad = "\n".join(layering_violations(graph))
    assert "brush_env.engine.simulator:1 imports brush_env.motion.trajectory" in bad
    assert "brush_env.engine.simulator:3 imports agents.train" in bad  # inside a function
    assert "brush_env.envs:1 imports agents" in bad
    # motion may import the engine
    assert not any(line.startswith("brush_env.motion.trajectory") for line in bad.splitlines())
    assert import_cycles(graph) == [["brush_env.engine.a", "brush_env.engine.b"]]
