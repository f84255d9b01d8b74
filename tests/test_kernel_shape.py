"""The engine's kernels stay readable (issue 10): few named arguments, no tuples read by position.

Read from the source with ``ast``: every numba kernel (a function decorated with ``njit``) takes at
most 10 arguments, the kernels' data travel as the named records of ``engine/records.py``, and no
engine module reads a context or Newton-cache tuple by position (``ctx[1]``, ``jac[4]``) or a
column of the body-parameter table by a bare number (``bp[i, 4]``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ENGINE = Path(__file__).resolve().parents[1] / "brush_env" / "engine"
MAX_KERNEL_ARGS = 10


def _kernels():
    for path in sorted(ENGINE.glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and any(
                "njit" in ast.unparse(d) for d in node.decorator_list
            ):
                yield path.name, node


def test_engine_has_kernels():
    assert len(list(_kernels())) > 20


@pytest.mark.parametrize("name,node", list(_kernels()), ids=lambda v: getattr(v, "name", v))
def test_kernel_takes_at_most_ten_arguments(name, node):
    n = len(node.args.args)
    assert n <= MAX_KERNEL_ARGS, f"{name}:{node.name} takes {n} arguments"


def _subscripts(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name):
            yield node


@pytest.mark.parametrize("path", sorted(ENGINE.glob("*.py")), ids=lambda p: p.name)
def test_no_position_indexed_context_or_parameter_columns(path):
    bad = []
    for node in _subscripts(ast.parse(path.read_text())):
        name = node.value.id
        sl = node.slice
        if name in ("ctx", "jac", "ws", "sw", "small") and isinstance(sl, ast.Constant):
            bad.append(ast.unparse(node))
        # bp[i, 4]: a parameter column by number (the columns are records.B_*)
        if name == "bp" and isinstance(sl, ast.Tuple) and len(sl.elts) == 2:
            col = sl.elts[1]
            if isinstance(col, ast.Constant) or (
                isinstance(col, ast.Slice) and isinstance(col.lower, ast.Constant)
            ):
                bad.append(ast.unparse(node))
    assert not bad, f"{path.name}: {bad}"
