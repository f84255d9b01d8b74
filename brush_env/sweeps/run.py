"""One run of a sweep: the variant's files, the reference experiment, its metrics (issue 16).

``prepare(spec, run)`` writes the variant's brush, materials and scene files into the run's
folder and loads them, so a bad variant (e.g. sections that overlap) is found before any run
starts.  ``execute(job)`` runs ``run_reference`` there and writes:

* ``summary.json``: the run's id, motion, parameters and metrics, without timings, so the same
  spec gives byte-identical files on any executor (``json.dumps(..., sort_keys=True)``, floats by
  ``repr``);
* ``timing.json``: wall time and the host;
* the experiment's own outputs in ``experiment/``;
* ``error.json`` instead when the run fails (the message; the sweep goes on).

Units: as the metrics (``spec.METRICS``).
"""

from __future__ import annotations

import copy
import json
import math
import os
import socket
import time
import traceback
from pathlib import Path

import numpy as np

from .safety import move_aside, write_text
from .spec import CIRCLE_METRICS, METRICS, SweepSpec, base_tables, resolve


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} to TOML")


def dump_toml(d: dict) -> str:
    """A small TOML writer for config dicts (scalars, lists, tables, arrays of tables)."""
    lines, tables = [], []
    for k, v in d.items():
        if isinstance(v, dict) or (isinstance(v, list) and v and isinstance(v[0], dict)):
            tables.append((k, v))
        else:
            lines.append(f"{k} = {_toml_value(v)}")

    def emit(prefix, v):
        if isinstance(v, dict):
            sub = [(k, x) for k, x in v.items() if isinstance(x, dict)]
            lines.append(f"\n[{prefix}]")
            for k, x in v.items():
                if not isinstance(x, dict):
                    lines.append(f"{k} = {_toml_value(x)}")
            for k, x in sub:
                emit(f"{prefix}.{k}", x)
        else:
            for item in v:
                lines.append(f"\n[[{prefix}]]")
                for k, x in item.items():
                    lines.append(f"{k} = {_toml_value(x)}")

    for k, v in tables:
        emit(k, v)
    return "\n".join(lines) + "\n"


def prepare(spec: SweepSpec, run: dict, out: Path) -> dict:
    """Write the run's variant files into ``out/runs/<id>`` and check they load; returns the job
    (everything ``execute`` needs, plain data)."""
    from ..engine import load_brush, load_scene

    bases = base_tables(spec.path, {"brush": spec.brush, "scene": spec.scene})
    brush, mat, scene = (copy.deepcopy(bases[k]) for k in ("brush", "material", "scene"))
    motion = dict(spec.motion)
    for key, value in run["params"].items():
        head, _, rest = key.partition(".")
        if head == "motion":
            motion[rest] = value
        else:
            resolve({"brush": brush, "material": mat, "scene": scene}[head], rest, value)
    d = out / "runs" / run["id"]
    d.mkdir(parents=True, exist_ok=True)
    materials = {brush.get("material", "m"): mat}
    write_text(d / "materials.toml", dump_toml(materials))
    brush = {**brush, "materials_file": "materials.toml"}
    write_text(d / "brush.toml", dump_toml(brush))
    scene = {**scene, "brush": str(d / "brush.toml")}
    write_text(d / "scene.toml", dump_toml(scene))
    load_scene(d / "scene.toml", brush=load_brush(d / "brush.toml"))  # a bad variant fails here
    return dict(
        id=run["id"],
        motion=run["motion"],
        params=run["params"],
        dir=str(d),
        fidelity=spec.fidelity,
        kwargs=motion,
        metrics=list(spec.metrics),
    )


def done(job: dict) -> bool:
    """A finished run (its summary.json, or error.json of a recorded failure) is not redone."""
    d = Path(job["dir"])
    return (d / "summary.json").is_file() or (d / "error.json").is_file()


def execute(job: dict) -> dict:
    """Run one job (in any process); returns {id, status, metrics or error, run_time_s}."""
    from ..engine.warmup import ensure_compiled
    from ..experiments.run import run_reference

    d = Path(job["dir"])
    t0 = time.perf_counter()
    try:
        ensure_compiled()  # loads the cached kernels (compiles once per machine)
        kw = dict(job["kwargs"])
        if job["motion"] == "press":
            kw["turns"] = 0.01  # the press and hold only (the circle barely starts)
        if job["motion"] == "pitch":
            kw["pitch_error_deg"] = 1.0
        summary = run_reference(
            scene=str(d / "scene.toml"),
            out_dir=str(d / "experiment"),
            fidelity=job["fidelity"],
            progress=False,
            plots=False,
            **kw,
        )
        wall = time.perf_counter() - t0
        m, why = metrics(summary, d / "experiment", job["motion"])
        wanted = [k for k in job["metrics"] if k != "run_time_s"]
        result = dict(
            id=job["id"],
            motion=job["motion"],
            params=job["params"],
            status=summary["status"],
            metrics={k: m.get(k) for k in wanted},
            blank={k: why[k] for k in wanted if m.get(k) is None},
        )
        # timing first: summary.json is what marks the run done (both written atomically)
        timing = {"run_time_s": wall, "host": socket.gethostname(), "pid": os.getpid()}
        write_text(d / "timing.json", json.dumps(timing))
        write_text(d / "summary.json", json.dumps(result, sort_keys=True, indent=1) + "\n")
        return {**result, "run_time_s": wall}
    except Exception as e:  # recorded, never stops the sweep
        err = dict(
            id=job["id"],
            motion=job["motion"],
            params=job["params"],
            status="failed",
            error=f"{type(e).__name__}: {e}",
            traceback=traceback.format_exc(limit=5),
        )
        write_text(d / "error.json", json.dumps(err, sort_keys=True, indent=1) + "\n")
        return {**err, "run_time_s": time.perf_counter() - t0}


class DamagedFile(ValueError):
    """A run's stored JSON cannot be read; ``path`` names it."""

    def __init__(self, path: Path, why: str) -> None:
        super().__init__(f"{path}: {why}")
        self.path = path


def _read_json(path: Path, job: dict, keys: tuple) -> dict:
    try:
        r = json.loads(path.read_text())
    except (ValueError, UnicodeDecodeError) as e:  # JSONDecodeError is a ValueError
        raise DamagedFile(path, f"not valid JSON ({e})") from None
    if not isinstance(r, dict) or any(k not in r for k in keys):
        raise DamagedFile(path, f"not a run record (needs the keys {list(keys)})")
    if "id" in keys and r["id"] != job["id"]:
        raise DamagedFile(path, f"holds run {r['id']!r}, not {job['id']!r}")
    return r


def load_result(job: dict) -> dict:
    """The stored result of a finished run (summary.json or error.json, plus its timing).
    Raises ``DamagedFile`` naming the first file that cannot be read."""
    d = Path(job["dir"])
    if (d / "summary.json").is_file():
        r = _read_json(d / "summary.json", job, ("id", "status", "metrics"))
        t = d / "timing.json"
        if t.is_file():
            r["run_time_s"] = _read_json(t, job, ("run_time_s",))["run_time_s"]
        else:
            r["run_time_s"] = None
            r.setdefault("blank", {})["run_time_s"] = "timing.json missing"
        return r
    r = _read_json(d / "error.json", job, ("id", "status", "error"))
    r["run_time_s"] = None
    return r


def set_aside_damaged(job: dict, err: DamagedFile) -> list[Path]:
    """Move a damaged run's stored results aside (``safety.move_aside``) so the run is redone;
    returns the new paths."""
    d = Path(job["dir"])
    moved = [err.path]
    moved += [d / n for n in ("summary.json", "error.json", "timing.json") if d / n != err.path]
    return [move_aside(p) for p in moved if p.is_file()]


def metrics(summary: dict, exp_dir: Path, motion: str = "circle") -> tuple[dict, dict]:
    """METRICS of a run_reference summary (baseline run) and its tips.npz, and for each metric
    left blank (None) the reason (the sweep's table shows it in the error column)."""
    a = summary["analysis"]["baseline"]
    out = dict.fromkeys(METRICS)
    why: dict[str, str] = {}
    out["peak_Fh_N"] = a.get("max_Fh_N")
    out["peak_Fz_N"] = a.get("max_abs_Fz_N")
    out["mean_Fz_N"] = a.get("mean_Fz_N")
    out["mean_Fn_N"] = a.get("mean_Fn_total_N")
    out["max_penetration_mm"] = a.get("max_penetration_whole_run_mm")
    if motion == "press":
        # measured on the circle after its first quarter: a press has none
        for k in CIRCLE_METRICS:
            out[k] = None
            why[k] = "n/a for motion press (no circle)"
    elif a.get("note"):
        for k in CIRCLE_METRICS:
            why[k] = f"n/a: {a['note']} (the circle metrics start there)"
    jam = (a.get("jamming") or {}).get("events", {})
    # jam1: the event the paper puts at 9pi/4 (45 deg mod 360), jam2: 13pi/4 (225 deg)
    events = sorted(jam.values(), key=lambda ev: ev.get("paper_angle_mod_2pi_rad", 0.0))
    for i, ev in enumerate(events[:2], start=1):
        if motion != "press" and ev.get("count"):
            out[f"jam{i}_angle_deg"] = ev.get("mean_angle_mod_2pi_deg")
            out[f"jam{i}_peak_N"] = ev.get("mean_Fh_N")
    for i, paper in ((1, 45), (2, 225)):
        for k in (f"jam{i}_angle_deg", f"jam{i}_peak_N"):
            why.setdefault(k, f"no jamming peak detected near the paper's {paper} deg")
    try:
        ts = np.genfromtxt(exp_dir / "timeseries.csv", delimiter=",", names=True)
        out["peak_Fn_N"] = float(np.max(ts["Fn_total_N"]))
        out["mean_Ft_N"] = float(np.mean(ts["Ft_abs_sum_N"]))
    except (OSError, ValueError, KeyError) as e:
        for k in ("peak_Fn_N", "mean_Ft_N"):
            why[k] = f"timeseries.csv unreadable ({type(e).__name__}: {e})"
    try:
        with np.load(exp_dir / "tips.npz") as z:
            per_tip = z["tip_normal_force"].mean(axis=0)
        mu = float(per_tip.mean())
        out["tip_load_spread"] = float(per_tip.std() / mu) if mu > 0 else None
        why["tip_load_spread"] = "no tip load (mean tip normal force is 0)"
    except (OSError, ValueError, KeyError) as e:
        why["tip_load_spread"] = f"tips.npz unreadable ({type(e).__name__}: {e})"
    for k, v in out.items():
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v)):
            out[k] = None
            why[k] = f"not finite ({v!r}; run status {summary.get('status')!r})"
        elif v is None:
            why.setdefault(k, "not in the reference experiment's summary")
    return out, {k: why[k] for k, v in out.items() if v is None}
