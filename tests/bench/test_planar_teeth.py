"""``bench planar`` and ``bench teeth``: the commands' rows (no timing asserted).

bench planar: both cuts, every phase, the stability trials; a planar chain along a row cannot
buckle out of its plane, so the 3-D tips leave that plane and not the cross-row one.
bench teeth: both scenes ran, and every crown's grid stays inside the rigorous sqrt(3) h bound.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from brush_env import cli


@pytest.mark.slow  # a bench CLI run (~3 s)
def test_bench_planar_quick_rows(capsys):
    assert cli.main(["bench", "planar", "--quick", "--json", "--plot", ""]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    err = [r for r in rows if r["table"] == "error"]
    assert {(r["cut"], r["phase"]) for r in err} >= {("y", "press + hold"), ("x", "press + hold")}
    by = {(r["cut"], r["phase"]): r for r in err}
    assert by[("y", "press + hold")]["out_of_plane_max_mm"] < 1e-6
    speed = [r for r in rows if r["table"] == "speed"]
    assert {r["cut"] for r in speed} == {"x", "y"}
    for r in speed:
        assert any(t["ok"] for t in r["trials"]) and not all(t["ok"] for t in r["trials"])


@pytest.mark.slow  # ~6 s: bakes and steps the tooth row
def test_bench_teeth_quick_rows(capsys):
    assert cli.main(["bench", "teeth", "--quick", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    speed = [r for r in rows if r["table"] == "speed"]
    assert [r["scene"] for r in speed] == ["flat_plate", "tooth_row"]
    assert all(r["status"] == "ok" for r in speed)
    sdf = [r for r in rows if r["table"] == "sdf"]
    assert len(sdf) == 4
    assert all(r["band_max_err_mm"] <= r["bound_mm"] for r in sdf)


@pytest.mark.slow  # ~36 s: bakes and steps both ellipsoid scenes
def test_bench_teeth_ellipsoid_rows_are_one_surface_twice():
    """``--ellipsoids`` compares analytic ellipsoids with the same ellipsoids baked into grids:
    outside each surface, within the band, the grid's distance must match the closed-form one
    (sdf.ellipsoid_gap, itself tested against a numerical minimum) within the trilinear error
    (3/8) h^2 max|Hess d| <= (3/8) h^2 / r_min (r_min = a_min^2 / a_max, the smallest radius of
    curvature) plus the facet sagitta e^2 / (8 r_min) of the mesh's longest edge e."""
    from brush_env.bench.teeth import ellipsoid_scenes
    from brush_env.engine import mesh_contact, sdf
    from brush_env.engine.surfaces import surface_gap

    analytic, baked = ellipsoid_scenes("fast")
    assert [s.label for s in analytic.surfaces][-1] == "gum"
    rng = np.random.default_rng(0)
    mesh, grids = mesh_contact.empty_mesh(), sdf.empty_sdf()
    for e, m in zip(analytic.surfaces[:4], baked.surfaces[:4], strict=True):
        row = np.atleast_1d(e.kernel_row())
        ax = np.asarray(e.semi_axes)
        r_min = ax.min() ** 2 / ax.max()
        V, T = m.vertices, m.triangles
        edge = np.linalg.norm(V[T] - V[np.roll(T, 1, axis=1)], axis=2).max()
        bound = 3 / 8 * m.cell**2 / r_min + edge**2 / (8 * r_min)
        u = rng.normal(size=(400, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        P = np.asarray(e.center) + u * ax * rng.uniform(1.0, 1.2, (400, 1))
        d_ex = np.array([surface_gap(row, 0, p, np.zeros(3), np.zeros(3), mesh, grids) for p in P])
        d_gr, _ = m.sdf_grid().query(P)
        near = (d_ex > 0.0) & (d_ex < 0.8)
        assert near.sum() > 200
        assert np.abs(d_gr - d_ex)[near].max() <= bound, (e.label, bound)


@pytest.mark.slow  # two bench CLI runs (~4 s)
def test_bench_steps_is_deterministic(capsys):
    """``bench steps`` is for A/B comparisons by Newton iterations: the same run twice gives the
    same count (the engine's determinism), over the whole one-stroke motion."""
    rows = []
    for _ in range(2):
        assert cli.main(["bench", "steps", "--scene", "tooth_row", "--strokes", "1", "--json"]) == 0
        rows.append(json.loads(capsys.readouterr().out.splitlines()[-1]))
    assert rows[0]["steps"] == rows[1]["steps"] > 1500  # 1.59 s of press, hold and stroke at 1 ms
    assert rows[0]["newton_iterations"] == rows[1]["newton_iterations"] > rows[0]["steps"]


def test_bench_steps_refuses_a_bad_stroke_count(capsys):
    assert cli.main(["bench", "steps", "--strokes", "0"]) == 2
    assert "--strokes = 0" in capsys.readouterr().err
