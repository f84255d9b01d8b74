"""``brush-env reference --scene tooth_row [--mesh FILE]``: the press-and-scrub experiment writes
its files and per-region coverage; a user's mesh replaces the crowns; bad meshes are refused
before anything runs, with the reason (not closed, wrong units)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brush_env.cli import main
from brush_env.engine import ConfigError
from brush_env.experiments.tooth_row import run_tooth_row
from brush_env.geometry.meshes import load_mesh_file

QUICK = dict(strokes=1, x_range=(-2.0, 2.0), press_time=0.2, hold_time=0.05, dt=2e-3)


def test_tooth_row_run_writes_the_outputs_with_region_coverage(tmp_path):
    s = run_tooth_row(brush="tiny", out_dir=tmp_path, progress=False, **QUICK)
    assert s["status"] == "ok"
    for f in ("timeseries.csv", "tips.npz", "summary.json", "forces_vs_time.png", "coverage.png"):
        assert (tmp_path / f).is_file(), f
    summary = json.loads((tmp_path / "summary.json").read_text())
    cov = summary["analysis"]["coverage"]
    assert set(cov["regions"]) == {"buccal", "occlusal", "interproximal", "lingual"}
    assert set(cov["teeth"]) == {"PM1", "PM2", "M1", "M2"}
    assert 0.0 < cov["reachable"] < 1.0 and cov["regions"]["lingual"] == 0.0
    ts = np.genfromtxt(tmp_path / "timeseries.csv", delimiter=",", names=True)
    # statics of the whole brush: the TCP's z force balances the contact's (gravity is tiny)
    assert np.nanmax(ts["Fn"]) > 0.1
    assert summary["surfaces"][-1] == "gum"


def _icosphere_stl(path, radius=4.0, scale=1.0):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    m.apply_scale(scale)
    m.export(path)
    return m


def test_user_mesh_replaces_the_crowns_from_the_cli(tmp_path, capsys):
    stl = tmp_path / "my_tooth.stl"
    _icosphere_stl(stl)
    out = tmp_path / "run"
    code = main(
        ["reference", "--scene", "tooth_row", "--mesh", str(stl), "--brush", "tiny",
         "--out", str(out), "--no-progress", "--dt", "0.002"]
    )  # fmt: skip
    assert code == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["surfaces"] == ["tooth:user", "gum"]
    assert "coverage" in capsys.readouterr().out


def test_open_mesh_and_wrong_units_are_refused_with_the_reason(tmp_path):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=2, radius=4.0)
    open_mesh = trimesh.Trimesh(m.vertices, m.faces[:-3])
    f = tmp_path / "open.stl"
    open_mesh.export(f)
    with pytest.raises(ConfigError, match=r"not closed \(\d+ open edges\)"):
        load_mesh_file(f)
    g = tmp_path / "metres.stl"
    _icosphere_stl(g, scale=1e-3)  # an 8 mm tooth written in metres
    with pytest.raises(ConfigError, match=r"read as 'm' it would be 8 mm \(--mesh-units m\)"):
        load_mesh_file(g, "mm")
    V, T = load_mesh_file(g, "m")
    assert np.ptp(V, axis=0).max() == pytest.approx(8.0, rel=1e-3)
    with pytest.raises(ConfigError, match=r"mesh = .*: no such file"):
        load_mesh_file(tmp_path / "none.stl")
