"""docs/architecture.md: every `file:function` of the equation table exists, and every module of
the package map is a real file."""

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


def test_package_map_names_real_modules():
    rows = re.findall(
        r"^\| `((?:engine|motion|experiments|validation|bench|envs)/[^`]+)` \|", DOC, re.M
    )
    assert len(rows) >= 20
    for row in rows:
        folder = row.split("/")[0]
        for part in re.findall(r"\{([\w,]+)\}\.py|([\w]+)\.py", row):
            for name in part[0].split(",") if part[0] else [part[1]]:
                assert (ROOT / "brush_env" / folder / f"{name}.py").is_file(), row
