"""No module reaches into another module's private names (issue 27): ``from X import _name`` and
``X._name`` (X a module of ``brush_env`` or ``agents``) fail unless X is the module itself, and a
private module (``brush_env.engine._kernels``) is imported only from inside its own package.
Dunder names (``__version__``, ``__all__``) are public.  Read from the source alone (``ast``).

``ALLOWED`` lists the crossings that stay for now, each with its reason; it may only shrink.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("brush_env", "agents")

#: (importing module, imported module, name): crossings that stay, with the reason (none now)
ALLOWED: dict[tuple[str, str, str], str] = {}


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _modname(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(node: ast.ImportFrom, mod: str, is_pkg: bool) -> str:
    if not node.level:
        return node.module or ""
    package = mod if is_pkg else mod.rpartition(".")[0]
    parts = package.split(".")
    base = ".".join(parts[: len(parts) - node.level + 1])
    return f"{base}.{node.module}" if node.module else base


def _private_module(target: str, mod: str) -> bool:
    """``target`` lies inside a private module or package that ``mod`` is not part of."""
    parts = target.split(".")
    for k, part in enumerate(parts):
        if _private(part):
            owner = ".".join(parts[:k])  # the package holding the private module
            return not (mod == owner or mod.startswith(owner + "."))
    return False


def _imports(tree, mod, is_pkg, known, out) -> dict[str, str]:
    """Record private names taken by import statements in ``out``; returns the local names that
    stand for modules of ``known`` (``import a.b``, ``from a import b``, ``as`` names)."""
    alias: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name not in known:
                    continue
                if _private_module(a.name, mod):
                    out.append((node.lineno, a.name, "<module>"))
                alias[a.asname or a.name.split(".")[0]] = (
                    a.name if a.asname else a.name.split(".")[0]
                )
        elif isinstance(node, ast.ImportFrom):
            target = _resolve(node, mod, is_pkg)
            if target in known and _private_module(target, mod):
                out.append((node.lineno, target, "<module>"))
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in known:  # a module: from pkg import module (as m)
                    alias[a.asname or a.name] = sub
                    if _private_module(sub, mod):
                        out.append((node.lineno, sub, "<module>"))
                elif _private(a.name) and target in known and target != mod:
                    out.append((node.lineno, target, a.name))
    return alias


def _attributes(tree, mod, known, alias, out) -> None:
    """Record ``module._name`` attribute uses (through the local module names) in ``out``."""
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and _private(node.attr)):
            continue
        chain = []
        v: ast.AST = node.value
        while isinstance(v, ast.Attribute):
            chain.append(v.attr)
            v = v.value
        if isinstance(v, ast.Name) and v.id in alias:
            target = ".".join([alias[v.id], *reversed(chain)])
            if target in known and target != mod:
                out.append((node.lineno, target, node.attr))


def crossings(source: str, mod: str, is_pkg: bool, known: set[str]) -> list[tuple[int, str, str]]:
    """(line, imported module, private name) of every private name ``source`` takes from
    another module of ``known`` (name ``"<module>"``: the import of a private module from
    outside its package)."""
    tree = ast.parse(source)
    out: list[tuple[int, str, str]] = []
    alias = _imports(tree, mod, is_pkg, known, out)
    _attributes(tree, mod, known, alias, out)
    return sorted(set(out))


def _modules() -> dict[str, Path]:
    return {_modname(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def test_no_private_name_crosses_modules():
    mods = _modules()
    known = set(mods)
    bad = []
    for mod, path in mods.items():
        for line, target, name in crossings(
            path.read_text(), mod, path.name == "__init__.py", known
        ):
            if (mod, target, name) not in ALLOWED:
                bad.append(f"{path.relative_to(ROOT)}:{line}: {target}.{name}")
    assert bad == [], "private names used across modules:\n" + "\n".join(bad)


def test_allowed_list_is_current():
    mods = _modules()
    known = set(mods)
    seen = set()
    for mod, path in mods.items():
        for _, target, name in crossings(path.read_text(), mod, path.name == "__init__.py", known):
            seen.add((mod, target, name))
    assert set(ALLOWED) <= seen, f"stale ALLOWED entries: {sorted(set(ALLOWED) - seen)}"


def test_checker_sees_both_forms():
    known = {"pkg", "pkg.a", "pkg.b"}
    src = (
        "from pkg.a import _x, y, __all__\n"
        "from . import a\n"
        "import pkg.b\n"
        "from .b import _y\n"
        "a._z\n"
        "pkg.b._w\n"
        "a.__dict__\n"
    )
    got = crossings(src, "pkg.c", False, known)
    assert got == [
        (1, "pkg.a", "_x"),
        (4, "pkg.b", "_y"),
        (5, "pkg.a", "_z"),
        (6, "pkg.b", "_w"),
    ]
    assert crossings("from ._q import f\n", "pkg.c", False, {"pkg", "pkg._q"}) == []
    outside = crossings("from pkg._q import f\n", "other.m", False, {"pkg", "pkg._q"})
    assert outside == [(1, "pkg._q", "<module>")]
