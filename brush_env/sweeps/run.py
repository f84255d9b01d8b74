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

from .spec import METRICS, SweepSpec, base_tables, resolve


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
    (d / "materials.toml").write_text(dump_toml(materials))
    brush = {**brush, "materials_file": "materials.toml"}
    (d / "brush.toml").write_text(dump_toml(brush))
    scene = {**scene, "brush": str(d / "brush.toml")}
    (d / "scene.toml").write_text(dump_toml(scene))
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
        m = metrics(summary, d / "experiment")
        result = dict(
            id=job["id"],
            motion=job["motion"],
            params=job["params"],
            status=summary["status"],
            metrics={k: m.get(k) for k in job["metrics"] if k != "run_time_s"},
        )
        (d / "summary.json").write_text(json.dumps(result, sort_keys=True, indent=1) + "\n")
        (d / "timing.json").write_text(
            json.dumps({"run_time_s": wall, "host": socket.gethostname(), "pid": os.getpid()})
        )
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
        (d / "error.json").write_text(json.dumps(err, sort_keys=True, indent=1) + "\n")
        return {**err, "run_time_s": time.perf_counter() - t0}


def load_result(job: dict) -> dict:
    """The stored result of a finished run (summary.json or error.json, plus its timing)."""
    d = Path(job["dir"])
    if (d / "summary.json").is_file():
        r = json.loads((d / "summary.json").read_text())
        t = d / "timing.json"
        r["run_time_s"] = json.loads(t.read_text())["run_time_s"] if t.is_file() else None
        return r
    r = json.loads((d / "error.json").read_text())
    r["run_time_s"] = None
    return r


def metrics(summary: dict, exp_dir: Path) -> dict:
    """METRICS of a run_reference summary (baseline run) and its tips.npz."""
    a = summary["analysis"]["baseline"]
    out = dict.fromkeys(METRICS)
    out["peak_Fh_N"] = a.get("max_Fh_N")
    out["peak_Fz_N"] = a.get("max_abs_Fz_N")
    out["mean_Fz_N"] = a.get("mean_Fz_N")
    out["mean_Fn_N"] = a.get("mean_Fn_total_N")
    out["max_penetration_mm"] = a.get("max_penetration_whole_run_mm")
    jam = (a.get("jamming") or {}).get("events", {})
    # jam1: the event the paper puts at 9pi/4 (45 deg mod 360), jam2: 13pi/4 (225 deg)
    events = sorted(jam.values(), key=lambda ev: ev.get("paper_angle_mod_2pi_rad", 0.0))
    for i, ev in enumerate(events[:2], start=1):
        if ev.get("count"):
            out[f"jam{i}_angle_deg"] = ev.get("mean_angle_mod_2pi_deg")
            out[f"jam{i}_peak_N"] = ev.get("mean_Fh_N")
    try:
        ts = np.genfromtxt(exp_dir / "timeseries.csv", delimiter=",", names=True)
        out["peak_Fn_N"] = float(np.max(ts["Fn_total_N"]))
        out["mean_Ft_N"] = float(np.mean(ts["Ft_abs_sum_N"]))
        with np.load(exp_dir / "tips.npz") as z:
            per_tip = z["tip_normal_force"].mean(axis=0)
        mu = float(per_tip.mean())
        out["tip_load_spread"] = float(per_tip.std() / mu) if mu > 0 else None
    except (OSError, ValueError, KeyError):
        pass
    return {k: (None if v is None or (isinstance(v, float) and not math.isfinite(v)) else v)
            for k, v in out.items()}  # fmt: skip
