"""Hashes of the engine's outputs on fixed runs, for refactors that must not change a bit
(issue 27).

Run ``python -m tests.golden [--quick] [--tips-only] [--out FILE]``: it prints one line per
case, ``case sha256 steps``, hashing every array a step reports (TCP wrench, tips, contact
forces and flags, Newton iterations).  Compare the file against one written before the change
(``diff``).  Cases: the plate press-and-drag at ``fast`` with both beam elements and at
``balanced`` (coupled tip-tip), the tooth row's press-and-scrub (``bench steps``'s motion), a
FlatPlate-v0 episode under fixed random actions, and a part of a turn of the reference
experiment (its ``timeseries.csv`` and ``tips.npz``).  ``--tips-only`` loads every scene file
with ``shaft_contact`` and ``head_contact`` off (the tip-only contact model before issue 28),
whose hashes must equal the ones written before shaft contact existed.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
from pathlib import Path

import numpy as np


def _feed(h, res) -> None:
    for name in (
        "tcp_force",
        "tcp_moment",
        "tip_pos",
        "tip_vel",
        "tip_normal_force",
        "tip_tangential_force",
        "tip_in_contact",
        "tip_sliding",
        "tip_penetration",
        "tip_contact_point",
    ):
        h.update(np.ascontiguousarray(getattr(res, name)).tobytes())
    h.update(np.array([res.time, res.iterations, res.substeps], float).tobytes())


def _settings(level: str, **over):
    from brush_env.engine.fidelity import load_fidelity

    return load_fidelity(level).settings(**over)


def _bodies(level: str) -> int:
    from brush_env.engine.fidelity import load_fidelity

    return load_fidelity(level).bodies_per_bristle


def plate_press_drag(level: str, element: str, steps: int) -> tuple[str, int]:
    from brush_env.engine import Simulator
    from brush_env.experiments.plan import resolve_scene

    scene = resolve_scene(None, "flat_plate", _bodies(level))
    sim = Simulator(scene, _settings(level, dt=2e-3, element=element))
    R = np.diag([1.0, -1.0, -1.0])
    z0 = sim.touch_height(R, 0.0) + 0.2
    h = hashlib.sha256()
    _feed(h, sim.reset(np.array([0.0, 0.0, z0]), R))
    n_press = steps // 2
    for k in range(1, steps + 1):
        if k <= n_press:  # 2.7 mm press in n_press steps
            p = np.array([0.0, 0.0, z0 - 2.7 * k / n_press])
        else:  # drag along x at 20 mm/s
            p = np.array([0.04 * (k - n_press), 0.0, z0 - 2.7])
        _feed(h, sim.step(p, R))
    return h.hexdigest(), steps


def tooth_row(level: str, max_steps: int) -> tuple[str, int]:
    from brush_env.engine import Simulator
    from brush_env.experiments.plan import resolve_scene
    from brush_env.experiments.tooth_row import DEFAULTS, scrub_motion

    dt = DEFAULTS["dt"]
    sim = Simulator(resolve_scene(None, "tooth_row", _bodies(level)), _settings(level, dt=dt))
    traj, _ = scrub_motion(sim, {**DEFAULTS, "strokes": 1})
    ts = np.arange(min(int(traj.duration / dt), max_steps)) * dt
    P, R, _, _ = traj.sample(ts)
    h = hashlib.sha256()
    _feed(h, sim.reset(P[0], R[0]))
    for k in range(1, len(ts)):
        _feed(h, sim.step(P[k], R[k]))
    return h.hexdigest(), len(ts) - 1


def env_episode(level: str, steps: int, env_id: str = "FlatPlate-v0") -> tuple[str, int]:
    import gymnasium as gym

    import brush_env  # noqa: F401  (registers the envs)

    env = gym.make(f"brush_env/{env_id}", fidelity=level)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(3)
    h = hashlib.sha256(np.asarray(obs).tobytes())
    n = 0
    for _ in range(steps):
        a = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        a[2] = -0.5 * abs(a[2])  # press down gently so that contact happens
        obs, r, term, trunc, _ = env.step(a)
        h.update(np.asarray(obs).tobytes())
        h.update(np.array([r, term, trunc], float).tobytes())
        n += 1
        if term or trunc:
            break
    env.close()
    return h.hexdigest(), n


def reference_run(level: str, turns: float) -> tuple[str, int]:
    from brush_env.experiments.run import run_reference

    with tempfile.TemporaryDirectory() as d:
        run_reference(out_dir=d, turns=turns, fidelity=level, progress=False, plots=False)
        data = (Path(d) / "timeseries.csv").read_bytes()
        h = hashlib.sha256(data)
        with np.load(Path(d) / "tips.npz") as z:
            for key in sorted(z.files):
                h.update(np.ascontiguousarray(z[key]).tobytes())
    return h.hexdigest(), data.count(b"\n")


def tips_only() -> None:
    """Every scene file loads with shaft and head contact off (patches ``load_scene`` where the
    golden cases' callers look it up)."""
    import dataclasses

    import brush_env.engine as eng
    import brush_env.engine.scene as scn
    import brush_env.envs.flat_plate as fp
    import brush_env.experiments.plan as plan

    orig = scn.load_scene

    def load(*a, **k):
        return dataclasses.replace(orig(*a, **k), shaft_contact=False, head_contact=False)

    for mod in (eng, scn, fp, plan):
        mod.load_scene = load  # type: ignore[attr-defined]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps per case")
    ap.add_argument("--out", help="also write the lines to this file")
    ap.add_argument(
        "--tips-only", action="store_true", help="scenes with shaft and head contact off"
    )
    a = ap.parse_args(argv)
    if a.tips_only:
        tips_only()
    q = a.quick
    cases = {
        "plate_coarse_mid": lambda: plate_press_drag("coarse", "mid", 150 if q else 400),
        "plate_coarse_paper": lambda: plate_press_drag("coarse", "paper", 150 if q else 400),
        "plate_balanced_mid": lambda: plate_press_drag("balanced", "mid", 80 if q else 200),
        "tooth_row_coarse": lambda: tooth_row("coarse", 300 if q else 1200),
        "env_coarse": lambda: env_episode("coarse", 40 if q else 100),
        "reference_coarse": lambda: reference_run("coarse", 0.3 if q else 0.6),
        "reference_balanced": lambda: reference_run("balanced", 0.05 if q else 0.15),
        "env_tooth_row_coarse": lambda: env_episode("coarse", 30 if q else 80, "ToothRow-v0"),
    }
    lines = []
    for name, fn in cases.items():
        digest, n = fn()
        line = f"{name} {digest} {n}"
        print(line, flush=True)
        lines.append(line)
    if a.out:
        Path(a.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
