"""The house's layering, read from the code's own imports (ast, nothing executed), and the
engine's independence from gymnasium (subprocesses)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "brush_env"

#: what each room must never import (module-name prefixes)
FORBIDDEN = {
    "brush_env.engine": (
        "brush_env.motion",
        "brush_env.experiments",
        "brush_env.bench",
        "brush_env.validation",
        "brush_env.envs",
        "brush_env.cli",
        "agents",
        "gymnasium",
        "torch",
        "stable_baselines3",
        "matplotlib",
    ),
    "brush_env.motion": (
        "brush_env.experiments",
        "brush_env.bench",
        "brush_env.validation",
        "brush_env.envs",
        "agents",
        "gymnasium",
    ),
    "brush_env.validation": (
        "brush_env.experiments",
        "brush_env.bench",
        "brush_env.envs",
        "agents",
    ),
    "brush_env.experiments": ("brush_env.bench", "brush_env.envs", "agents"),
    "brush_env.envs": (
        "brush_env.experiments",
        "brush_env.bench",
        "brush_env.validation",
        "agents",
    ),
}


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """Absolute names of the modules a file imports (relative imports resolved)."""
    mod = _module_name(path)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module
            out.add(name)
            out.update(f"{name}.{a.name}" for a in node.names)  # `from pkg import module`
    return out


def _all_modules() -> dict[str, set[str]]:
    return {_module_name(p): _imports(p) for p in sorted(PKG.rglob("*.py"))}


def test_the_rooms_exist():
    for room in FORBIDDEN:
        assert (ROOT / room.replace(".", "/")).is_dir(), room


@pytest.mark.parametrize("room", list(FORBIDDEN))
def test_nothing_imports_upward(room):
    bad = []
    for mod, imps in _all_modules().items():
        if mod == room or mod.startswith(room + "."):
            for imp in imps:
                if any(imp == f or imp.startswith(f + ".") for f in FORBIDDEN[room]):
                    bad.append(f"{mod} imports {imp}")
    assert not bad, bad


def test_no_circular_imports_between_modules():
    """Module-level imports between brush_env modules form no cycle (a package's __init__ that
    re-exports its own submodules is not a cycle of the code)."""
    mods = _all_modules()
    graph = {
        m: {i for i in imps if i in mods and i != m and not m.startswith(i + ".")}
        for m, imps in mods.items()
    }
    state: dict[str, int] = {}
    cycles = []

    def visit(m, stack):
        state[m] = 1
        for n in graph[m]:
            if n.startswith(m + "."):
                continue  # a package importing its own submodule
            if state.get(n) == 1:
                cycles.append(stack[stack.index(n) :] + [n] if n in stack else [m, n])
            elif n not in state:
                visit(n, stack + [n])
        state[m] = 2

    for m in graph:
        if m not in state:
            visit(m, [m])
    assert not cycles, cycles


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300
    )


def test_engine_import_does_not_load_gymnasium():
    r = _run(
        "import sys, brush_env.engine, brush_env.motion, brush_env.experiments\n"
        "assert 'gymnasium' not in sys.modules, 'gymnasium loaded'\n"
    )
    assert r.returncode == 0, r.stderr


def test_engine_runs_with_gymnasium_blocked():
    """As on a machine without gymnasium: a finder refuses it; the engine builds and steps."""
    r = _run(
        "import sys, importlib.abc\n"
        "class Block(importlib.abc.MetaPathFinder):\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name.split('.')[0] == 'gymnasium':\n"
        "            raise ImportError('gymnasium is blocked')\n"
        "sys.meta_path.insert(0, Block())\n"
        "import numpy as np\n"
        "from brush_env.engine import Simulator, SimSettings, load_scene\n"
        "sim = Simulator(load_scene('flat_plate', brush='tiny'), SimSettings())\n"
        "R = np.diag([1.0, -1.0, -1.0])\n"
        "sim.reset(np.array([0.0, 0.0, 20.0]), R)\n"
        "out = sim.step(np.array([0.0, 0.0, 20.0]), R)\n"
        "assert np.isfinite(out.tcp_force).all()\n"
    )
    assert r.returncode == 0, r.stderr


@pytest.mark.parametrize(
    "order",
    [
        "import brush_env\nimport gymnasium as gym",
        "import gymnasium as gym\nimport brush_env",
        "import gymnasium as gym",
    ],
)
def test_ids_registered_in_any_import_order(order):
    env_id = (
        "brush_env:brush_env/FlatPlate-v0" if "brush_env" not in order else "brush_env/FlatPlate-v0"
    )
    r = _run(
        f"{order}\n"
        f"env = gym.make({env_id!r}, brush='tiny_env', max_episode_steps=7)\n"
        "assert env.unwrapped.horizon == 7, env.unwrapped.horizon\n"
        f"assert gym.make({env_id!r}, brush='tiny_env').unwrapped.horizon == 300\n"
    )
    assert r.returncode == 0, r.stderr
