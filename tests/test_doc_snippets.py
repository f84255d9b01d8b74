"""Every Python snippet in README.md and docs/*.md runs as written (each in a fresh interpreter,
from the repository root), and the designer's snippet starts with the tips just touching."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _snippets():
    for path in FILES:
        for k, code in enumerate(re.findall(r"```python\n(.*?)```", path.read_text(), re.S)):
            yield pytest.param(code, id=f"{path.name}-{k}")


SNIPPETS = list(_snippets())


def test_there_are_snippets():
    assert len(SNIPPETS) >= 2


@pytest.mark.slow  # a fresh interpreter per snippet (~7 s in all)
@pytest.mark.parametrize("code", SNIPPETS)
def test_snippet_runs(code):
    r = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stderr[-2000:]


def test_designer_snippet_first_step_is_gentle():
    """The README's designer snippet resets at ``sim.touch_height`` and starts the press
    smoothly: its first step must read a tiny force (< 0.05 N), not the several newtons of tips
    started inside the plate."""
    code = next(
        c
        for c in re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
        if "touch_height" in c
    )
    ns: dict = {}
    exec(compile(code, "README.md", "exec"), ns)  # noqa: S102 - the README's own example
    assert abs(ns["first"].tcp_force[2]) < 0.05
