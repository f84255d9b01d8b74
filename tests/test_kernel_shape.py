"""The engine's kernels stay readable (issue 10): few named arguments, no tuples read by position.

Read from the source with ``ast``: every numba kernel (a function decorated with ``njit``) takes at
most 10 arguments, the kernels' data travel as the named records of ``engine/records.py``, and no
engine module reads a context or Newton-cache tuple by position (``ctx[1]``, ``jac[4]``), a
column of the body-parameter table by a bare number (``bp[i, 4]``) or any column by a named
column constant (``ts[:, S_FN]``, ``prm[P_H]``, ``st[S_FT + 1]``; issue 27): records are read by
field name (``st.fn``, ``prm.h``, ``ts["fn"]``).
"""

from __future__ import annotations

import ast
import re
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
        # bp[i, 4]: a parameter column by number (records.BODY has named fields)
        if name == "bp" and isinstance(sl, ast.Tuple) and len(sl.elts) == 2:
            col = sl.elts[1]
            if isinstance(col, ast.Constant) or (
                isinstance(col, ast.Slice) and isinstance(col.lower, ast.Constant)
            ):
                bad.append(ast.unparse(node))
    assert not bad, f"{path.name}: {bad}"


#: a column constant: ``S_FN``, ``P_H``, ``B_HALF``, ``SURF_MESH`` (also as ``ct.S_FN``)
COLUMN = re.compile(r"^[A-Z]+_[A-Z0-9_]+$")
#: (module, source of the subscript) -> why its constant index is legitimate
ALLOWED: dict[tuple[str, str], str] = {}


def _column_name(node):
    """The column constant ``node`` names (a Name or module attribute, or one plus an offset,
    ``S_FT + 1``), else None."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        node = node.left
    name = node.id if isinstance(node, ast.Name) else getattr(node, "attr", None)
    if isinstance(node, (ast.Name, ast.Attribute)) and COLUMN.match(name):
        return name
    return None


def column_subscripts(source: str) -> list[str]:
    """Subscripts whose index (the last element of a tuple index, or the index itself; a slice's
    start) is a column constant."""
    bad = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Subscript):
            continue
        idx = node.slice
        if isinstance(idx, ast.Tuple) and idx.elts:
            idx = idx.elts[-1]
        if isinstance(idx, ast.Slice):
            idx = idx.lower
        if idx is not None and _column_name(idx):
            bad.append(ast.unparse(node))
    return bad


def test_the_column_check_catches_columns():
    src = "ts[:, S_FT:S_FT + 3]; prm[P_H]; st[S_FT + 1]; X[a, b, ct.S_FN]; bp[i, B_JX]"
    assert len(column_subscripts(src)) == 5
    assert column_subscripts("st.fn; ts['fn']; x[SURF_FLOATS * s : n]; a[i, 0]; b[N]") == []


@pytest.mark.parametrize("path", sorted(ENGINE.glob("*.py")), ids=lambda p: p.name)
def test_no_column_constant_indexes(path):
    bad = [s for s in column_subscripts(path.read_text()) if (path.name, s) not in ALLOWED]
    assert not bad, f"{path.name}: read by field name instead: {bad}"
