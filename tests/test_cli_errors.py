"""User mistakes through the real command lines: one stderr line, exit code 2, no traceback, and
nothing written (issue: the first hour of a new user)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PPO_TYPO = """
algo = "ppo"
[env]
config = "flat_plate"
[hyperparameters]
n_step = 64
"""


MISTAKES = {
    "missing brush file": (
        ["-m", "brush_env.cli", "reference", "--brush", "nonexistent.toml", "--out", "OUT"],
        "does not exist",
    ),
    "misspelled brush name": (
        ["-m", "brush_env.cli", "reference", "--brush", "defualt", "--out", "OUT"],
        "did you mean default",
    ),
    "unknown subcommand": (["-m", "brush_env.cli", "referense"], "invalid choice"),
    "missing agent config": (
        [
            "-m",
            "agents.train",
            "--algo",
            "ppo",
            "--config",
            "missing.toml",
            "--timesteps",
            "10",
            "--out",
            "OUT",
        ],
        "no such file",
    ),
    "misspelled hyperparameter": (
        [
            "-m",
            "agents.train",
            "--algo",
            "ppo",
            "--config",
            "ppo.toml",
            "--timesteps",
            "10",
            "--n-envs",
            "2",
            "--out",
            "OUT",
        ],
        "did you mean n_steps",
    ),
    "env key typo": (
        [
            "-m",
            "agents.train",
            "--algo",
            "ppo",
            "--config",
            str(ROOT / "configs/agents/ppo.toml"),
            "--timesteps",
            "10",
            "--n-envs",
            "2",
            "--env-kw",
            "max_episode_step=5",
            "--out",
            "OUT",
        ],
        "did you mean max_episode_steps",
    ),
    # issue 28: inputs that ran (or crashed) before
    "static friction below dynamic": (
        ["-m", "brush_env.cli", "reference", "--scene", "mu.toml", "--out", "OUT"],
        "contact.mu_s = 0.3 is out of range: must be >= contact.mu_d = 0.76",
    ),
    "zero plate normal": (
        ["-m", "brush_env.cli", "reference", "--scene", "normal.toml", "--out", "OUT"],
        "surface[0].normal = [0.0, 0.0, 0.0] is invalid: must be a non-zero 3-vector",
    ),
    "tip spheres overlapping at rest": (
        ["-m", "brush_env.cli", "reference", "--brush", "tip5.toml", "--out", "OUT"],
        "tip_radius_mm = 5) overlap by 8.4 mm at rest",
    ),
    "SDF grid too large": (
        ["-m", "brush_env.cli", "reference", "--scene", "box.toml", "--out", "OUT"],
        "box150.obj': mesh: cell_mm = 0.15 is too fine for a mesh of 150 x 150 x 150 mm",
    ),
    "duplicated key in a scene file": (
        ["-m", "brush_env.cli", "reference", "--scene", "dup.toml", "--out", "OUT"],
        "dup.toml: invalid TOML",
    ),
    "unknown brush in a scene file": (
        ["-m", "brush_env.cli", "reference", "--scene", "nobrush.toml", "--out", "OUT"],
        "brush = 'nosuchbrush': brush 'nosuchbrush' is not a known brush",
    ),
    "tooth mesh in cm read as mm": (
        [
            "-m",
            "brush_env.cli",
            "reference",
            "--scene",
            "tooth_row",
            "--mesh",
            "arch_cm.obj",
            "--brush",
            "tiny",
            "--out",
            "OUT",
        ],
        "smallest extent is 1 mm with units = 'mm', outside [4, 40] mm",
    ),  # fmt: skip
    "self-intersecting mesh": (
        [
            "-m",
            "brush_env.cli",
            "reference",
            "--scene",
            "tooth_row",
            "--mesh",
            "crossing.obj",
            "--brush",
            "tiny",
            "--out",
            "OUT",
        ],
        "the surface intersects itself",
    ),  # fmt: skip
    "press deeper than the bristles": (
        [
            "-m",
            "brush_env.cli",
            "reference",
            "--press-depth",
            "15",
            "--turns",
            "0.01",
            "--out",
            "OUT",
        ],
        # issue 31: under the flag's name, the value in the flag's unit
        "--press-depth = 15 mm is out of range: must be >= 0 and < 10 (mm), below the bristles' "
        "free length 10 mm",
    ),  # fmt: skip
    "missing policy": (
        ["-m", "agents.evaluate", "--policy", "missing.zip", "--episodes", "1", "--out", "OUT"],
        "not one of reference, reference-static, reference-sliding, 'random'",
    ),
}


def box_obj(size, offsets=((0.0, 0.0, 0.0),)) -> str:
    """An OBJ file of closed, outward-wound boxes of ``size`` (x, y, z) [file units], one per
    offset (overlapping offsets: a self-intersecting mesh)."""
    corners = [(i, j, k) for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    quads = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))
    lines = []
    for n, off in enumerate(offsets):
        lines += [
            "v " + " ".join(f"{c * s + o:g}" for c, s, o in zip(cn, size, off)) for cn in corners
        ]
        for a, b, c, d in quads:
            a, b, c, d = (8 * n + x + 1 for x in (a, b, c, d))
            lines += [f"f {a} {b} {c}", f"f {a} {c} {d}"]
    return "\n".join(lines) + "\n"


SCENE = (ROOT / "configs/scenes/flat_plate.toml").read_text()
BRUSH = (ROOT / "configs/brushes/default.toml").read_text()
#: the input files of the MISTAKES below, written into the test's working directory
FILES = {
    "ppo.toml": PPO_TYPO,
    "mu.toml": SCENE.replace("mu_s = 0.8 ", "mu_s = 0.3 "),
    "normal.toml": SCENE.replace("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]"),
    "dup.toml": SCENE.replace("tip_tip = true", "tip_tip = true\ntip_tip = false"),
    "nobrush.toml": SCENE.replace('brush = "default"', 'brush = "nosuchbrush"'),
    "tip5.toml": BRUSH.replace("tip_radius_mm = 0.44", "tip_radius_mm = 5.0"),
    "box150.obj": box_obj((150.0, 150.0, 150.0)),
    "box.toml": '[[surface]]\nkind = "mesh"\nfile = "box150.obj"\n',
    "arch_cm.obj": box_obj((5.0, 1.0, 1.0)),  # a 50 x 10 x 10 mm row in cm
    "crossing.obj": box_obj((6.0, 6.0, 6.0), ((0, 0, 0), (3.0, 2.0, 1.0))),
}


# ~35 s: a fresh `python -m ...` per mistake (full CLI runs); quick tier: test_cli_messages.py
@pytest.mark.slow
@pytest.mark.parametrize("name", list(MISTAKES))
def test_user_mistake_gives_one_line_and_exit_code_2(name, tmp_path):
    args, expected = MISTAKES[name]
    for fname, text in FILES.items():
        (tmp_path / fname).write_text(text)
    args = [a.replace("OUT", str(tmp_path / "out")) for a in args]
    r = subprocess.run(
        [sys.executable, *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr and expected in lines[0], lines[0]
    assert not (tmp_path / "out").exists()  # nothing written before the inputs are valid


@pytest.mark.slow  # a full CLI run in a fresh interpreter
def test_debug_shows_the_traceback(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "brush_env.cli", "reference", "--brush", "defualt", "--debug"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode != 0 and "Traceback" in r.stderr
