"""Design sweeps (issue 16): bad specs fail before any run with one line; a sweep resumes without
redoing finished runs; the local pool and a local Ray instance give byte-identical run
summaries; the sensitivity ranking recovers a known linear model."""

from __future__ import annotations

import os

import numpy as np
import pytest

from brush_env.engine import ConfigError
from brush_env.sweeps import load_spec, read_table, run_sweep, sweep_report
from brush_env.sweeps.report import src

TINY = """
name = "tiny"
brush = "tiny"
fidelity = "coarse"
motions = ["circle"]
metrics = ["peak_Fh_N", "peak_Fz_N", "mean_Fn_N", "tip_load_spread", "run_time_s"]
[sample]
method = "grid"
[motion]
turns = 0.3
[[vary]]
key = "material.E_MPa"
values = [5.0, 9.0]
[[vary]]
key = "brush.sections.*.width_mm"
values = [1.2, 1.6]
unit = "mm"
"""


def _spec(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "change, message",
    [
        (('key = "material.E_MPa"', 'key = "material.E_GPa"'), r"key 'material.E_GPa'.*unknown"),
        (("values = [5.0, 9.0]", "values = []"), r"values is empty"),
        (('unit = "mm"', 'unit = "cm"'), r"unit = 'cm', but the key is in 'mm'"),
        (('motions = ["circle"]', 'motions = ["spiral"]'), r"'spiral' is not one of"),
        (('fidelity = "coarse"', 'fidelty = "coarse"'), r"unknown; did you mean fidelity"),
    ],
)
def test_bad_specs_fail_before_any_run_with_one_line(tmp_path, change, message):
    p = _spec(tmp_path, TINY.replace(*change))
    with pytest.raises(ConfigError, match=message) as e:
        run_sweep(p, tmp_path / "out", progress=False)
    assert "\n" not in str(e.value)
    assert not (tmp_path / "out").exists()


def test_empty_range_and_a_variant_that_cannot_be_built_fail_before_any_run(tmp_path):
    text = TINY.replace('method = "grid"', 'method = "lhs"\nn = 4').replace(
        "values = [5.0, 9.0]", "range = [9.0, 5.0]"
    )
    with pytest.raises(ConfigError, match=r"range = \[9.0, 5.0\] is empty: need lo < hi \(MPa\)"):
        load_spec(_spec(tmp_path, text))
    # 2.5 mm wide sections at a 2.2 mm pitch overlap: found while preparing, nothing runs
    p = _spec(tmp_path, TINY.replace("values = [1.2, 1.6]", "values = [1.2, 2.5]"), "o.toml")
    with pytest.raises(ConfigError, match="overlap"):
        run_sweep(p, tmp_path / "out2", progress=False)
    assert not list((tmp_path / "out2").glob("runs/*/summary.json"))


# ~5 s: two real sweeps and a report (the quick tier resumes through the CLI test below)
@pytest.mark.slow
def test_sweep_resumes_without_redoing_finished_runs(tmp_path):
    p = _spec(tmp_path, TINY)
    out = tmp_path / "out"
    first = run_sweep(p, out, workers=1, progress=False, limit=2)
    assert (first["done_before"], first["ran"]) == (0, 2)
    done = sorted(out.glob("runs/*/summary.json"))
    stamps = {f: os.stat(f).st_mtime_ns for f in done}
    again = run_sweep(p, out, workers=2, progress=False)
    assert (again["done_before"], again["ran"], again["failed"]) == (2, 2, 0)
    assert all(os.stat(f).st_mtime_ns == stamps[f] for f in done)
    cols, units, rows = read_table(out / "results.csv")
    assert len(rows) == 4 and {r["status"] for r in rows} == {"ok"}
    assert units[cols.index("material.E_MPa")] == "MPa"
    # a stiffer material presses harder at the same geometry (same width): the physics is there
    by = {(r["material.E_MPa"], r["brush.sections.*.width_mm"]): r for r in rows}
    assert by[(9.0, 1.2)]["mean_Fn_N"] > by[(5.0, 1.2)]["mean_Fn_N"]
    report = sweep_report(out)
    text = report.read_text()
    assert "Which parameter moves the peak forces most" in text
    assert (out / "effect_material_E_MPa.png").is_file()


@pytest.mark.slow  # Ray (~18 s: a local Ray instance)
def test_local_pool_and_ray_give_byte_identical_summaries(tmp_path):
    ray = pytest.importorskip("ray")  # the [cluster] extra; CI installs it (.ci/run)
    p = _spec(tmp_path, TINY)
    run_sweep(p, tmp_path / "local", workers=2, progress=False)
    try:
        run_sweep(p, tmp_path / "ray", ray_address="local", progress=False)
    finally:
        if ray.is_initialized():
            ray.shutdown()
    local = sorted((tmp_path / "local").glob("runs/*/summary.json"))
    assert len(local) == 4
    for f in local:
        g = tmp_path / "ray" / "runs" / f.parent.name / "summary.json"
        assert f.read_bytes() == g.read_bytes(), f.parent.name


def test_src_ranks_a_known_linear_model():
    """y = 3 x1 + 0.5 x2 + 0 x3 with independent uniform inputs: SRC_i = b_i sd_i / sd_y exactly
    for a linear model, R^2 = 1."""
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 1, (200, 3))
    y = 3 * X[:, 0] + 0.5 * X[:, 1]
    s, r2 = src(X, y)
    sd = X.std(axis=0)
    np.testing.assert_allclose(s, np.array([3.0, 0.5, 0.0]) * sd / y.std(), atol=1e-12)
    assert r2 == pytest.approx(1.0)
    assert np.argmax(np.abs(s)) == 0


def test_cli_limit_runs_the_first_variants_and_the_full_sweep_resumes(tmp_path, capsys):
    """``brush-env sweep SPEC --limit 2``: the spec's first two variants only; ``--dry-run`` then
    lists all four (two done) with the time the rest should take from the two measured; the full
    sweep afterwards runs the other two and leaves the first two as they were."""
    from brush_env import cli

    p = _spec(tmp_path, TINY)
    out = tmp_path / "out"
    base = ["sweep", str(p), "--out", str(out), "--workers", "1", "--no-progress"]
    assert cli.main([*base, "--limit", "2"]) == 0
    said = capsys.readouterr().out
    assert "4 runs: 0 already done, 2 run now" in said and "2 more without --limit" in said
    done = sorted(out.glob("runs/*/summary.json"))
    assert [f.parent.name for f in done] == ["circle_0000", "circle_0001"]
    stamps = {f: os.stat(f).st_mtime_ns for f in done}

    assert cli.main(["sweep", str(p), "--out", str(out), "--workers", "1", "--dry-run"]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert listing[0].split() == [
        "id", "motion", "material.E_MPa", "[MPa]", "brush.sections.*.width_mm", "[mm]", "status"
    ]  # fmt: skip
    status = {ln.split()[0]: ln.split()[-1] for ln in listing[1:5]}
    assert status == {"circle_0000": "done", "circle_0001": "done",
                      "circle_0002": "run", "circle_0003": "run"}  # fmt: skip
    assert "4 variants" in listing[-1] and "2 done in" in listing[-1]
    assert "2 to run; estimated" in listing[-1] and "the median run time of 2 run(s)" in listing[-1]
    assert sorted(out.glob("runs/*/summary.json")) == done  # the dry run ran nothing

    assert cli.main(base) == 0
    assert "4 runs: 2 already done, 2 run now" in capsys.readouterr().out
    assert all(os.stat(f).st_mtime_ns == stamps[f] for f in done)
    assert len(read_table(out / "results.csv")[2]) == 4


def test_dry_run_before_any_run_says_how_to_measure_one(tmp_path, capsys):
    from brush_env import cli

    p = _spec(tmp_path, TINY)
    assert cli.main(["sweep", str(p), "--out", str(tmp_path / "out"), "--dry-run"]) == 0
    last = capsys.readouterr().out.splitlines()[-1]
    assert "0 done in" in last and "4 to run" in last
    assert "no run measured yet in --out: `--limit 1` runs the first and measures it" in last
    assert not (tmp_path / "out").exists()  # nothing written
