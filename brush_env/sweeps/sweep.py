"""``brush-env sweep SPEC --out DIR``: check the spec, prepare every run, skip the finished ones,
run the rest on the chosen executor, keep one table (issue 16).

The table is ``DIR/results.csv``: one row per run (id, motion, status, the varied parameters in
their units, the metrics, run time, error).  CSV, not Parquet:

* The table holds a few hundred rows of numbers. CSV opens in every tool a designer has
  (spreadsheet, pandas, R) and diffs in git.
* It needs no 30-MB dependency (pyarrow).
* Floats are written with ``repr``, so nothing is lost.

The table is rewritten after every finished run: an interrupted sweep resumes from what it holds,
and ``done`` skips the runs whose ``summary.json`` or ``error.json`` exists.  ``DIR/spec.toml``
is a copy of the spec; ``DIR/sweep.json`` holds the run list, the executor and the wall time.

Faults (issue 28, ``safety.py``): a sweep holds ``DIR/.lock`` while it runs (a second one stops
with ``SweepLocked``, naming the holder's PID); every file is written through a unique temp file
and ``os.replace``; a run whose summary.json, error.json or timing.json cannot be read is named
in one line on ``log``, its files are moved aside (``*.damaged-<UTC time>``) and it is redone.
Every blank metric of a run says why in the table's error column (``_explain``).
"""

from __future__ import annotations

import csv
import io
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ..engine.checks import Limit, check_int
from .executors import run_local, run_ray
from .run import DamagedFile, done, load_result, prepare, set_aside_damaged
from .safety import OutLock, remove_stale_temps, write_bytes, write_text
from .spec import METRICS, load_spec


def run_sweep(
    spec_path,
    out,
    *,
    workers: int | None = None,
    ray_address: str | None = None,
    progress: bool = True,
    limit: int | None = None,
    log: Callable[[str], None] | None = None,
) -> dict:
    """Run (or resume) a sweep; returns {runs, done_before, ran, failed, wall_s, table, damaged}.
    ``limit``: only the spec's first ``limit`` variants (a small budget first; a later run
    without it resumes into the full sweep).  ``log``: where the one-line notes go (a damaged
    file set aside; default stderr).  Raises ``SweepLocked`` when another sweep holds ``out``."""
    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    if limit is not None:
        check_int("limit", limit, Limit("variants", ge=1))
    spec = load_spec(spec_path)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with OutLock(out):
        return _run_locked(spec, out, workers, ray_address, progress, limit, log)


def _run_locked(spec, out: Path, workers, ray_address, progress, limit, log) -> dict:
    remove_stale_temps(out)
    jobs = [prepare(spec, r, out) for r in spec.runs()]  # every variant loads before any run
    write_bytes(out / "spec.toml", Path(spec.path).read_bytes())
    results, damaged = {}, []
    for j in jobs:
        if not done(j):
            continue
        try:
            results[j["id"]] = load_result(j)
        except DamagedFile as e:
            moved = set_aside_damaged(j, e)
            damaged.append(str(e.path))
            log(f"sweep: damaged {e} -- moved aside to {moved[0].name}; run {j['id']} is redone")
    todo = [j for j in jobs[:limit] if j["id"] not in results]
    before = len(results)
    t0 = time.perf_counter()

    def on_result(r):
        results[r["id"]] = r
        write_table(out / "results.csv", spec, jobs, results)

    if ray_address:
        run_ray(todo, ray_address, on_result, progress)
    else:
        run_local(todo, workers, on_result, progress)
    wall = time.perf_counter() - t0
    write_table(out / "results.csv", spec, jobs, results)
    info = dict(
        spec=str(spec.path),
        runs=len(jobs),
        limit=limit,
        done_before=before,
        ran=len(todo),
        failed=sum(1 for r in results.values() if r.get("status") != "ok"),
        executor=f"ray {ray_address}" if ray_address else f"local x {workers or 'all cores'}",
        wall_s=wall,
        table=str(out / "results.csv"),
        damaged=damaged,
    )
    write_text(out / "sweep.json", json.dumps(info, indent=1))
    return info


def plan_sweep(spec_path, out, workers: int | None = None, limit: int | None = None) -> dict:
    """What ``run_sweep`` would do, nothing run and nothing written into ``out``: every variant
    (the first ``limit``; each is prepared in a temporary folder, so a bad one fails here),
    which ones ``out`` already holds, and the time the rest would take from the runs measured
    there (their median run time, in waves of ``workers``; None before a first run is
    measured).  Returns {spec, runs: [{id, motion, params, done}], units, todo, measured_s,
    n_measured, workers, waves, estimate_s}."""
    import os
    import statistics
    import tempfile

    spec = load_spec(spec_path)
    out = Path(out)
    with tempfile.TemporaryDirectory(prefix="sweep_dry_run_") as tmp:
        jobs = [prepare(spec, r, Path(tmp)) for r in spec.runs()[:limit]]
    runs, times = [], []
    for j in jobs:
        job = {**j, "dir": str(out / "runs" / j["id"])}
        finished = done(job)
        if finished:
            try:
                t = load_result(job).get("run_time_s")
            except DamagedFile:
                finished, t = False, None  # the real run sets it aside and redoes it
            if t is not None:
                times.append(float(t))
        runs.append(dict(id=j["id"], motion=j["motion"], params=j["params"], done=finished))
    workers = workers or os.cpu_count() or 1
    todo = sum(1 for r in runs if not r["done"])
    measured = statistics.median(times) if times else None
    waves = -(-todo // workers)  # runs go in waves of `workers` at a time
    return dict(
        spec=str(spec.path),
        runs=runs,
        units={p.key: p.unit for p in spec.params},
        todo=todo,
        measured_s=measured,
        n_measured=len(times),
        workers=workers,
        waves=waves,
        estimate_s=None if measured is None else waves * measured,
    )


def _explain(r: dict, metric_cols: list) -> str:
    """The error column: the error of a failed run, else why each blank metric is blank."""
    if r.get("error"):
        return r["error"]
    notes = [] if r.get("status") in ("ok", None) else [f"run {r['status']}"]
    blank = r.get("blank") or {}
    m = r.get("metrics") or {}
    by_reason: dict[str, list[str]] = {}
    for c in metric_cols:
        v = r.get("run_time_s") if c == "run_time_s" else m.get(c)
        if v is None:
            why = blank.get(c, "not recorded (run from an older version: rerun it)")
            by_reason.setdefault(why, []).append(c)
    notes += [f"{', '.join(cs)}: {why}" for why, cs in by_reason.items()]
    return "; ".join(notes)


def write_table(path: Path, spec, jobs: list, results: dict) -> None:
    """Write results.csv atomically (a unique temp file, then os.replace)."""
    keys = [p.key for p in spec.params]
    cols = ["id", "motion", "status", *keys, *spec.metrics]
    if "run_time_s" not in cols:
        cols.append("run_time_s")
    cols.append("error")
    metric_cols = cols[3 + len(keys) : -1]
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(cols)
    w.writerow(["# unit", "", "", *[p.unit for p in spec.params],
                *[METRICS[m][0] for m in metric_cols], ""])  # fmt: skip
    for j in jobs:
        r = results.get(j["id"])
        if r is None:
            continue
        m = r.get("metrics") or {}
        row = [j["id"], j["motion"], r.get("status")]
        row += [repr(float(j["params"][k])) for k in keys]
        for c in metric_cols:
            v = r.get("run_time_s") if c == "run_time_s" else m.get(c)
            row.append("" if v is None else repr(float(v)))
        row.append(_explain(r, metric_cols))
        w.writerow(row)
    write_text(path, buf.getvalue())


def read_table(path) -> tuple[list[str], list[str], list[dict]]:
    """(columns, units, rows) of a results.csv (numbers as floats, blanks as None)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    cols, units = rows[0], rows[1]
    out = []
    for r in rows[2:]:
        d = {}
        for c, v in zip(cols, r, strict=True):
            if c in ("id", "motion", "status", "error"):
                d[c] = v
            else:
                d[c] = float(v) if v != "" else None
        out.append(d)
    return cols, units, out
