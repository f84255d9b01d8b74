"""A sweep survives faults (issue 28), tested with real processes: a SIGKILL-ed ``--workers 2``
sweep leaves no worker behind and resumes with nothing lost or doubled; a second sweep on the
same ``--out`` stops at once with one line naming the holder's PID; a truncated summary.json is
named, moved aside and its run redone; two processes hammering ``write_table`` never leave a
broken table; every blank metric is explained in the error column."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from brush_env.sweeps import read_table, run_sweep
from brush_env.user_errors import UserError

REPO = Path(__file__).resolve().parents[2]

SPEC = """
name = "faults"
brush = "tiny"
fidelity = "coarse"
motions = {motions}
[sample]
method = "grid"
[motion]
turns = {turns}
[[vary]]
key = "material.E_MPa"
values = {values}
"""


def _spec(tmp_path, motions='["circle"]', turns=0.3, values="[5.0, 9.0]"):
    p = tmp_path / "spec.toml"
    p.write_text(SPEC.format(motions=motions, turns=turns, values=values))
    return p


def _sweep_cli(spec, out, workers=1, **kw) -> subprocess.Popen:
    """``python -m brush_env.cli sweep`` in a new process (this checkout: cwd wins the import)."""
    cmd = [sys.executable, "-m", "brush_env.cli", "sweep", str(spec), "--out", str(out)]
    cmd += ["--workers", str(workers), "--no-progress"]
    return subprocess.Popen(
        cmd, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw
    )


def _children(pid: int) -> set[int]:
    """Live child processes of ``pid`` (from /proc)."""
    out = set()
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()  # after "pid (comm)": state, ppid, ...
        if int(fields[1]) == pid and fields[0] != "Z":
            out.add(int(d.name))
    return out


def _alive(pid: int) -> bool:
    """Any thread of ``pid`` still running (a dying process's leader shows Z before its other
    threads have let go of its files, the lock among them)."""
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            if (task / "stat").read_text().rsplit(")", 1)[1].split()[0] != "Z":
                return True
        except OSError:
            pass
    return False


def _wait(cond, timeout, what):
    t_end = time.monotonic() + timeout
    while time.monotonic() < t_end:
        if cond():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigkill_of_a_two_worker_sweep_leaves_no_worker_and_the_resume_loses_nothing(
    tmp_path, capsys
):
    spec = _spec(tmp_path, turns=3, values="[5.0, 6.0, 7.0, 8.0]")  # ~4 s per run
    out = tmp_path / "out"
    proc = _sweep_cli(spec, out, workers=2)
    try:
        _wait(lambda: len(_children(proc.pid)) == 2, 60, "two pool workers")
        workers = _children(proc.pid)
        _wait(lambda: any(out.glob("runs/*/summary.json")), 60, "the first finished run")
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    n_done = len(list(out.glob("runs/*/summary.json")))
    assert 1 <= n_done < 4, "kill the sweep while runs are in flight"
    try:
        _wait(lambda: not any(_alive(p) for p in workers), 5, f"workers {workers} to stop")
    finally:
        for p in workers:  # never leave them running, whatever the result
            if _alive(p):
                os.kill(p, signal.SIGKILL)
    stamps = {f: f.stat().st_mtime_ns for f in out.glob("runs/*/summary.json")}
    again = run_sweep(spec, out, workers=2, progress=False)
    assert (again["done_before"], again["ran"], again["failed"]) == (n_done, 4 - n_done, 0)
    assert "damaged" not in capsys.readouterr().err
    assert all(f.stat().st_mtime_ns == t for f, t in stamps.items())  # not redone
    _, _, rows = read_table(out / "results.csv")
    assert sorted(r["id"] for r in rows) == [f"circle_{i:04d}" for i in range(4)]
    assert {r["status"] for r in rows} == {"ok"}
    assert len(list(out.glob("runs/*/summary.json"))) == 4
    assert not list(out.glob("**/.tmp-*"))


@pytest.mark.slow
def test_a_second_sweep_on_one_dir_stops_with_one_line_naming_the_holder(tmp_path):
    spec = _spec(tmp_path, turns=6, values="[5.0]")  # ~8 s: the first sweep holds the dir
    out = tmp_path / "out"
    first = _sweep_cli(spec, out)
    try:
        _wait(lambda: (out / "runs").is_dir(), 60, "the first sweep to start")
        second = _sweep_cli(spec, out)
        _, err = second.communicate(timeout=60)
        assert first.poll() is None, "the second sweep returned only after the first finished"
        assert second.returncode == 2
        assert len(err.strip().splitlines()) == 1, err
        assert f"in use by another sweep (pid {first.pid}" in err
        with pytest.raises(UserError, match=rf"in use by another sweep \(pid {first.pid}\b"):
            run_sweep(spec, out, workers=1, progress=False)
        _, err1 = first.communicate(timeout=120)
        assert first.returncode == 0, err1
    finally:
        if first.poll() is None:
            first.kill()
    # the holder is gone: the lock is free again, and everything was done once
    info = run_sweep(spec, out, workers=1, progress=False)
    assert (info["done_before"], info["ran"]) == (1, 0)


@pytest.mark.slow  # ~9 s for the three: a real sweep per damaged file
@pytest.mark.parametrize("name", ["summary.json", "error.json", "timing.json"])
def test_a_damaged_run_file_is_named_moved_aside_and_its_run_redone(tmp_path, capsys, name):
    spec = _spec(tmp_path)
    out = tmp_path / "out"
    run_sweep(spec, out, workers=1, progress=False)
    bad, good = out / "runs" / "circle_0000", out / "runs" / "circle_0001"
    stamp = (good / "summary.json").stat().st_mtime_ns
    if name == "error.json":  # a recorded failure whose error.json was cut short
        (bad / "summary.json").unlink()
    text = (bad / "summary.json").read_text() if name != "error.json" else '{"id": "c'
    (bad / name).write_text(text[: len(text) // 2])  # truncated mid-string
    capsys.readouterr()
    info = run_sweep(spec, out, workers=1, progress=False)
    notes = capsys.readouterr().err.strip().splitlines()
    assert len(notes) == 1, notes
    assert str(bad / name) in notes[0] and "moved aside" in notes[0]
    assert (info["done_before"], info["ran"], info["failed"]) == (1, 1, 0)
    assert info["damaged"] == [str(bad / name)]
    aside = list(bad.glob(f"{name}.damaged-*"))
    assert len(aside) == 1 and aside[0].read_text() == text[: len(text) // 2]
    assert json.loads((bad / "summary.json").read_text())["id"] == "circle_0000"
    assert (good / "summary.json").stat().st_mtime_ns == stamp
    _, _, rows = read_table(out / "results.csv")
    assert [r["status"] for r in rows] == ["ok", "ok"]


WRITER = """
import sys
from pathlib import Path
from brush_env.sweeps.spec import load_spec
from brush_env.sweeps.sweep import write_table

spec_path, table, value, n = sys.argv[1], Path(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
spec = load_spec(spec_path)
jobs = [dict(id=f"circle_{i:04d}", motion="circle", params={"material.E_MPa": 5.0})
        for i in range(200)]
results = {j["id"]: dict(status="ok", metrics=dict.fromkeys(spec.metrics, value),
                         run_time_s=value) for j in jobs}
for _ in range(n):
    write_table(table, spec, jobs, results)
"""


@pytest.mark.slow  # two processes rewriting one table 300 times each (~4 s)
def test_two_processes_writing_the_table_never_leave_a_broken_one(tmp_path):
    spec = _spec(tmp_path)
    table = tmp_path / "results.csv"
    script = tmp_path / "writer.py"
    script.write_text(WRITER)
    n = 300
    procs = [
        subprocess.Popen(
            [sys.executable, str(script), str(spec), str(table), v, str(n)],
            cwd=REPO,
            env={**os.environ, "PYTHONPATH": str(REPO)},
            stderr=subprocess.PIPE,
            text=True,
        )
        for v in ("1.0", "2.0")
    ]
    reads = 0
    try:
        while any(p.poll() is None for p in procs):
            if table.is_file():
                _, _, rows = read_table(table)  # a torn table fails here (row lengths)
                assert len(rows) == 200
                assert len({r["peak_Fh_N"] for r in rows}) == 1  # one writer's table, whole
                reads += 1
    finally:
        errs = [p.communicate(timeout=120)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    assert reads > 0
    _, _, rows = read_table(table)
    assert len(rows) == 200
    assert not list(tmp_path.glob(".tmp-*")) and not list(tmp_path.glob("*.tmp"))


def test_every_blank_metric_is_explained_in_the_error_column(tmp_path):
    spec = _spec(tmp_path, motions='["press", "circle"]', values="[7.0]")
    out = tmp_path / "out"
    run_sweep(spec, out, workers=1, progress=False)
    cols, _, rows = read_table(out / "results.csv")
    metrics = cols[cols.index("material.E_MPa") + 1 : cols.index("error")]
    by = {r["motion"]: r for r in rows}
    assert set(by) == {"press", "circle"} and {r["status"] for r in rows} == {"ok"}
    for r in rows:
        blank = [m for m in metrics if r[m] is None]
        assert all(m in r["error"] for m in blank), (r["id"], blank, r["error"])
    press = by["press"]
    for m in ("peak_Fh_N", "jam1_angle_deg", "jam2_peak_N"):
        assert press[m] is None
    assert "n/a for motion press" in press["error"]
    assert press["peak_Fn_N"] is not None and press["max_penetration_mm"] is not None
    summary = json.loads((out / "runs" / "press_0000" / "summary.json").read_text())
    assert summary["blank"]["peak_Fh_N"].startswith("n/a for motion press")
