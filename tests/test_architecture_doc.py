"""docs/architecture.md: every `file:function` of the equation table exists, every module of the
package map is a real file, and every module of brush_env/ and agents/ is in the map."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = (ROOT / "docs" / "architecture.md").read_text()


def _defined(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = {
        n.name
        for n in ast.walk(tree)
        if isinstance(n, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef))
    }
    names |= {
        t.id
        for n in tree.body
        if isinstance(n, ast.Assign)
        for t in n.targets
        if isinstance(t, ast.Name)
    }
    return names


def test_equation_table_points_at_real_functions():
    refs = re.findall(r"`(brush_env/[\w/]+\.py):(\w+)`", DOC)
    assert len(refs) >= 15
    for eq in range(1, 13):
        assert re.search(rf"^\| eq {eq} \|", DOC, re.M), f"eq {eq} missing from the table"
    for path, name in refs:
        assert (ROOT / path).is_file(), path
        assert name in _defined(ROOT / path), f"{path}:{name} not defined"


def _map_rows() -> list[str]:
    """The file cells of the package map: ``| `engine/checks.py` | ...`` (several per cell as
    `` `a.py`, `b.py` `` or ``{a,b}.py``)."""
    section = DOC.split("## Package map", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^\| (`[^|]+`) \|", section, re.M)


def listed_modules() -> set[Path]:
    """The files the package map names (paths relative to brush_env/, except agents/...)."""
    out = set()
    for cell in _map_rows():
        for item in re.findall(r"`([^`]+)`", cell):
            folder, _, rest = item.rpartition("/")
            braces = re.fullmatch(r"\{([\w,]+)\}\.py", rest)
            names = braces.group(1).split(",") if braces else [rest.removesuffix(".py")]
            base = ROOT if folder.split("/")[0] == "agents" else ROOT / "brush_env"
            out |= {base / folder / f"{n}.py" for n in names}
    return out


def package_modules() -> set[Path]:
    """Every module of brush_env/ and agents/ (package ``__init__.py`` files may be left out)."""
    return {
        p
        for pkg in ("brush_env", "agents")
        for p in (ROOT / pkg).rglob("*.py")
        if p.name != "__init__.py"
    }


def test_package_map_names_real_modules():
    listed = listed_modules()
    assert len(listed) >= 40
    missing = sorted(str(p.relative_to(ROOT)) for p in listed if not p.is_file())
    assert missing == [], f"the package map names files that do not exist: {missing}"


def test_every_module_is_in_the_package_map():
    absent = sorted(str(p.relative_to(ROOT)) for p in package_modules() - listed_modules())
    assert absent == [], f"modules missing from docs/architecture.md's package map: {absent}"


def test_ci_runs_the_readme_test_command():
    """.ci/run's last command is the README's test command (the install line's tail)."""
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()[-1]
    readme = (ROOT / "README.md").read_text()
    assert ci.startswith("ruff check . && ") and "python -m mypy" in ci
    assert f'pip install -e ".[rl,test,cluster]" && {ci}\n' in readme
    assert f"`{ci}`" in readme  # the Tests table's full tier
