"""``brush-env bench compile``: perf output parsing, the table and summary, and the whole pipeline
on one small kernel (``--quick``); the engine's own compile is too long for a test, and no timing
enters pass/fail."""

from __future__ import annotations

import json

import pytest

from brush_env import cli
from brush_env.bench.compile import format_report, parse_perf, summary

ROW_KEYS = {
    "run",
    "start",
    "settings",
    "wall_s",
    "cpu_s",
    "cpu_user_s",
    "import_s",
    "warmup_s",
    "instructions",
    "instructions_note",
    "maxrss_mb",
    "cache_files",
    "cache_bytes",
    "warmup_cpu_s",
    "llvm_s",
    "inline_s",
}


def test_parse_perf_counted_and_not():
    counted = "# started on ...\n\n123456789,,instructions:u,812345,100.00,,\n"
    assert parse_perf(counted) == (123456789, "")
    value, why = parse_perf("<not supported>,,instructions:u,0,100.00,,\n")
    assert value is None and "not supported" in why
    value, why = parse_perf("0.51,msec,task-clock,514856,100.00,0.428,CPUs utilized\n")
    assert value is None and "no instructions:u line" in why


def _row(run, start, cpu, instr):
    return {
        "run": run,
        "start": start,
        "settings": "s",
        "wall_s": cpu,
        "cpu_s": cpu,
        "warmup_s": cpu,
        "instructions": instr,
        "cache_files": 4,
        "cache_bytes": 4096,
        "maxrss_mb": 200.0,
    }


def test_summary_and_table():
    rows = [
        _row(1, "cold", 50.0, 2_000_000_000),
        _row(1, "cached", 2.0, None),
        _row(2, "cold", 55.0, 2_020_000_000),
        _row(2, "cached", 2.0, None),
    ]
    s = summary(rows)
    assert s["cold"]["cpu_s"] == pytest.approx(52.5)
    assert s["cold"]["cpu_s_spread"] == pytest.approx(0.1)
    assert s["cold"]["instructions_spread"] == pytest.approx(0.01)
    assert "instructions" not in s["cached"]  # n/a is not a number to summarise
    text = format_report(rows)
    assert text.count("\n| ") == 4 and "| 2.00e9 |" in text and "| n/a |" in text
    assert "cold, median: wall [s] 52.5 (spread 10.0 %)" in text


def test_cli_bench_compile_quick(capsys):
    assert cli.main(["bench", "compile", "--quick", "--json", "--repeats", "1"]) == 0
    rows = [json.loads(ln) for ln in capsys.readouterr().out.splitlines() if ln.startswith("{")]
    assert [r["start"] for r in rows] == ["cold (empty cache)", "cached (second start)"]
    assert all(set(r) == ROW_KEYS for r in rows)
    cold, cached = rows
    assert cold["cache_files"] >= 2 and cold["cache_bytes"] > 0  # it compiled into the new cache
    assert cached["cache_bytes"] == cold["cache_bytes"]  # ... and the second start only loaded it
    assert all(r["instructions"] is None or r["instructions"] > 0 for r in rows)
    # the split of the compile's CPU: LLVM compiled the kernel on the cold start, and the timed
    # parts lie within the warm-up's CPU (one small kernel, not inlined anywhere: no inlining)
    assert cold["llvm_s"] > 0.0 and cold["inline_s"] == 0.0
    for r in rows:
        assert r["llvm_s"] + r["inline_s"] <= r["warmup_cpu_s"] + 1e-3


def test_level_chooses_the_kernel_groups_the_start_compiles(capsys):
    """``--level``: the start's script warms the groups that level's runs compile."""
    import re

    from brush_env.bench.compile import warmup_script
    from brush_env.engine import SimSettings, warmup
    from brush_env.engine.fidelity import level_settings, load_fidelity

    ns = dict(warmup=warmup, SimSettings=SimSettings)
    ns.update(level_settings=level_settings, load_fidelity=load_fidelity)
    for level, groups in (
        ("all", warmup.GROUPS),
        ("default", warmup.groups_for(SimSettings(), follow=True)),
        ("balanced", warmup.groups_for(level_settings(load_fidelity("balanced")), follow=True)),
    ):
        script = warmup_script(level)
        expr = re.search(r"seconds = warmup\.warm_up\((.*)\)\n", script).group(1)
        assert eval(expr, ns) == groups
    assert warmup.FOLLOW_COUPLED in warmup.groups_for(
        level_settings(load_fidelity("balanced")), follow=True
    )
    assert cli.main(["bench", "compile", "--level", "nonsense", "--repeats", "1"]) != 0
    assert "'nonsense' is not a known fidelity level (known: balanced" in capsys.readouterr().err
