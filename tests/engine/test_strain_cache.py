"""The strain cache of the two-step formula (predict._prepare, NewtonCache.E / EK).

Reference: the formula itself.  ehist = c1 e_n + c2 e_{n-1} (eq 11 with the strains of eq 5)
must be the same numbers whether e_{n-1} is evaluated again from the t_{n-1} poses or taken from
the cache the previous step filled: the cache is keyed by those poses, so a run whose cache is
emptied before every step (every strain evaluated, as before the cache) and a run that keeps it
must agree to the bit -- through a press, stick and slip on the plate, halved sub-steps and the
coupled tip-tip solve's re-solves.
"""

from __future__ import annotations

import numpy as np
import pytest

from brush_env.engine import SimSettings, Simulator
from brush_env.engine.config import load_brush
from brush_env.engine.scene import load_scene

R = np.diag([1.0, -1.0, -1.0])  # bristles pointing down


def _run(sweeps: int, cache: str, dt: float = 2e-3):
    """The tiny brush pressed 0.6 mm into the plate, then dragged at 40 mm/s and back; every
    step's body positions and rotations, and the cache's keys after the last step.  cache:
    "kept", "emptied" before every step, or "corrupted" (its strains offset, its keys kept)."""
    brush = load_brush("tiny")
    scene = load_scene("flat_plate", brush=brush)
    top = max(b.length for b in brush.bristles) + brush.bristles[0].tip_radius
    sim = Simulator(scene, SimSettings(dt=dt, tip_tip_sweeps=sweeps, max_substep=1e-3))
    sim.reset(np.array([0.0, 0.0, top + 0.05]), R)
    st = sim.bristles.state
    rows = []
    for k in range(1, 121):
        z = top + 0.05 - min(k, 13) * 0.05
        x = 0.08 * max(k - 20, 0) if k < 70 else 0.08 * (120 - k)
        if cache == "emptied":
            st.jac.EK[:] = np.nan  # no key matches: every strain evaluated again
        elif cache == "corrupted":
            st.jac.E[:] += 1e-9
        sim.step(np.array([x, 0.0, z]), R)
        rows.append(np.concatenate([st.pos.ravel(), st.rot.ravel()]))
    return np.array(rows), st.jac.EK.copy()


def _first_bodies(sweeps):
    """Each bristle's first body (its element 0 has the base node as node A)."""
    brush = load_brush("tiny")
    scene = load_scene("flat_plate", brush=brush)
    return Simulator(scene, SimSettings(tip_tip_sweeps=sweeps)).model.bstart[:-1]


@pytest.mark.parametrize("sweeps", [1, 8])
def test_cached_strains_change_nothing(sweeps):
    kept, keys = _run(sweeps, "kept")
    fresh, _ = _run(sweeps, "emptied")
    wrong, _ = _run(sweeps, "corrupted")
    # every element's strain was cached: every body's pose and each bristle's base node
    assert np.isfinite(keys[:, 0:12]).all()
    assert np.isfinite(keys[_first_bodies(sweeps), 12:24]).all()
    assert np.array_equal(kept, fresh)  # to the bit, every step
    assert not np.array_equal(kept, wrong)  # and the steps do take e_{n-1} from the cache
