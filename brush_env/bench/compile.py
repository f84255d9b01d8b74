"""``bench compile``: the first-start numba compile of every kernel set, and the cached start.

Each repeat makes a new, empty ``NUMBA_CACHE_DIR`` (a temporary directory: nothing in the source
tree is deleted, and the package's own cache and stamp are left as they were) and runs, in a new
interpreter, what ``brush-env warmup`` runs (:func:`brush_env.engine.warmup.warm_up`): first
with the empty cache (the full compile), then again with the cache that run wrote (the cached
second start).  Per start it records the process's wall time, its CPU time (user + system, from
``getrusage(RUSAGE_CHILDREN)``), its peak memory, the files and bytes numba wrote to the cache,
and the user-space instructions it retired (``perf stat -e instructions:u``) where the machine's
PMU can count them; and, of the warm-up's CPU, the seconds in LLVM (llvmlite's calls:
optimisation, code generation, linking) and in numba's inlining of the ``inline="always"``
kernels (the rest is numba's own passes in Python: typing, lowering).

Wall time drifts by ~30 % on a shared VM and CPU time follows the machine's speed too; retired
instructions are the comparable figure between two versions of the engine (n/a on a VM without
a PMU, then compare CPU time of back-to-back runs).  The cache's bytes and files are
deterministic and show how much machine code the warm-up compiled.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .harness import markdown_table, open_log

PERF = "/usr/bin/perf"
EVENT = "instructions:u"
_MARK = "BENCH_COMPILE "

#: Where a start's compile CPU goes: LLVM (every llvmlite ffi call: optimisation, code generation,
#: linking) and numba's inlining of the ``inline="always"`` kernels
#: (``InlineWorker.inline_function``), each timed at its outermost call (both scripts below)
_TIMERS = """import llvmlite.binding.ffi as ffi
from numba.core import inline_closurecall as icc
acc = {"llvm": 0.0, "inline": 0.0}
def timed(key, fn):
    depth = [0]
    def wrapped(*a, **k):
        if depth[0]:
            return fn(*a, **k)
        depth[0] += 1
        c = time.process_time()
        try:
            return fn(*a, **k)
        finally:
            acc[key] += time.process_time() - c
            depth[0] -= 1
    return wrapped
ffi._lib_fn_wrapper.__call__ = timed("llvm", ffi._lib_fn_wrapper.__call__)
icc.InlineWorker.inline_function = timed("inline", icc.InlineWorker.inline_function)
"""

#: The full target: every kernel set, exactly as ``brush-env warmup`` compiles them.  The stamp
#: belongs to the package's own cache (``engine/__pycache__``): with another cache directory the
#: warm-up must neither sweep that cache's stale files nor stamp it as compiled.
_WARMUP = """
import json, resource, time
t0 = time.perf_counter()
from brush_env.engine import SimSettings, warmup
from brush_env.engine.fidelity import level_settings, load_fidelity
warmup.kernels_compiled = lambda *a: True  # no sweep of the package's own engine/__pycache__
warmup.write_stamp = lambda *a: None  # ... and no stamp (nor profile): it compiles elsewhere
#TIMERS
t1 = time.perf_counter()
c1 = time.process_time()
seconds = warmup.warm_up(GROUPS)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print("BENCH_COMPILE " + json.dumps({"import_s": t1 - t0, "warmup_s": seconds, "maxrss_kb": peak,
      "warmup_cpu_s": time.process_time() - c1, "llvm_s": acc["llvm"], "inline_s": acc["inline"]}))
""".replace("#TIMERS\n", _TIMERS)

#: ``--quick``: one small cached kernel; the same pipeline in seconds (for the tests).
_QUICK = """
import json, resource, time
t0 = time.perf_counter()
import numba, numpy as np
#TIMERS
t1 = time.perf_counter()
c1 = time.process_time()

@numba.njit(cache=True)
def norm2(x):
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * x[i]
    return s

norm2(np.ones(3))
t2, peak = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print("BENCH_COMPILE " + json.dumps({"import_s": t1 - t0, "warmup_s": t2 - t1, "maxrss_kb": peak,
      "warmup_cpu_s": time.process_time() - c1, "llvm_s": acc["llvm"], "inline_s": acc["inline"]}))
""".replace("#TIMERS\n", _TIMERS)


#: ``--level``: which kernel groups the start compiles (``GROUPS`` in the script above)
LEVEL_GROUPS = {
    "all": "warmup.GROUPS",  # brush-env warmup
    "default": "warmup.groups_for(SimSettings(), follow=True)",  # brush-env reference's set-up
}


def warmup_script(level: str = "all") -> str:
    """The start's script: the warm-up of every group ("all"), of the reference experiment's
    default set-up ("default") or of a fidelity level's (``warmup.groups_for``)."""
    groups = LEVEL_GROUPS.get(level)
    if groups is None:
        groups = f"warmup.groups_for(level_settings(load_fidelity({level!r})), follow=True)"
    return _WARMUP.replace("warmup.warm_up(GROUPS)", f"warmup.warm_up({groups})")


def perf_available(perf: str = PERF, event: str = EVENT) -> tuple[bool, str]:
    """Can ``perf stat`` count ``event`` here?  (ok, reason when not)."""
    if not Path(perf).is_file():
        return False, f"{perf} not found"
    with tempfile.NamedTemporaryFile("r", suffix=".perf") as out:
        try:
            subprocess.run(
                [perf, "stat", "-x,", "-e", event, "-o", out.name, "--", "true"],
                capture_output=True,
                timeout=30,
                check=True,
            )
        except (OSError, subprocess.SubprocessError) as e:
            return False, f"perf stat failed ({e})"
        value, reason = parse_perf(out.read(), event)
    return (value is not None), reason


def parse_perf(text: str, event: str = EVENT) -> tuple[int | None, str]:
    """The count of ``event`` in ``perf stat -x,`` output; (None, why) if it was not counted."""
    for line in text.splitlines():
        fields = line.split(",")
        if len(fields) >= 3 and fields[2] == event:
            if fields[0].strip().isdigit():
                return int(fields[0]), ""
            return None, f"perf: {event} {fields[0].strip() or 'missing'}"
    return None, f"perf: no {event} line"


def _cache_size(root: Path) -> tuple[int, int]:
    """Files and bytes numba wrote under ``root`` (its index ``.nbi`` and code ``.nbc`` files)."""
    files = [p for p in root.rglob("*") if p.is_file() and p.suffix in (".nbi", ".nbc")]
    return len(files), sum(p.stat().st_size for p in files)


def _engine_cache_snapshot() -> dict:
    """Name -> (size, mtime) of the package's own engine cache, to check it is left alone."""
    from brush_env.kernel_cache import ENGINE

    d = ENGINE / "__pycache__"
    if not d.is_dir():
        return {}
    return {
        p.name: (p.stat().st_size, p.stat().st_mtime_ns)
        for p in d.iterdir()
        if p.suffix in (".nbi", ".nbc", ".stamp")
    }


def run_start(script: Path, cache_dir: Path, perf: bool) -> dict:
    """One start of ``script`` in a new interpreter with ``NUMBA_CACHE_DIR = cache_dir``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
    cmd = [sys.executable, str(script)]
    perf_out = script.with_suffix(".perf")
    if perf:
        cmd = [PERF, "stat", "-x,", "-e", EVENT, "-o", str(perf_out), "--", *cmd]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(cmd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if out.returncode != 0:
        raise RuntimeError(f"bench compile: the start failed:\n{out.stderr[-2000:]}")
    marked = [ln for ln in out.stdout.splitlines() if ln.startswith(_MARK)]
    inner = json.loads(marked[-1][len(_MARK) :])
    instructions, why = parse_perf(perf_out.read_text()) if perf else (None, "")
    files, size = _cache_size(cache_dir)
    return {
        "wall_s": wall,
        "cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
        "cpu_user_s": after.ru_utime - before.ru_utime,
        "import_s": inner["import_s"],
        "warmup_s": inner["warmup_s"],
        "instructions": instructions,
        "instructions_note": why,
        "maxrss_mb": inner["maxrss_kb"] / 1024.0,  # the interpreter's own peak (kB on Linux)
        # the warm-up's CPU and, of it, LLVM's and numba's inlining's (_TIMERS)
        "warmup_cpu_s": inner["warmup_cpu_s"],
        "llvm_s": inner["llvm_s"],
        "inline_s": inner["inline_s"],
        "cache_files": files,
        "cache_bytes": size,
    }


def measure(
    repeats: int = 2, quick: bool = False, perf: bool | None = None, log=None, level: str = "all"
) -> list:
    """``repeats`` x (cold start with an empty cache, then the cached start): one row each.
    level: the kernel groups compiled (``warmup_script``)."""
    if perf is None:
        perf, why = perf_available()
        if not perf and log is not None:
            print(f"instructions: n/a ({why}); compare CPU time instead", file=log)
    rows = []
    settings = (
        "quick: one small kernel"
        if quick
        else f"warm_up(): tiny brush on flat_plate, kernel groups of --level {level}"
    )
    settings += f"; NUMBA_OPT={os.environ.get('NUMBA_OPT', 'default')}"
    # the warm-up's starts must compile into their own cache, never the package's; the quick
    # start's kernel is the script's own (it imports no brush_env), so there is nothing to check,
    # and the package's cache may change meanwhile for another reason (a test process compiling
    # beside it under pytest-xdist)
    before = None if quick else _engine_cache_snapshot()
    for rep in range(1, max(int(repeats), 1) + 1):
        with tempfile.TemporaryDirectory(prefix="bench_compile_") as tmp:
            script = Path(tmp) / "start.py"
            script.write_text(_QUICK if quick else warmup_script(level))
            cache = Path(tmp) / "numba_cache"
            cache.mkdir()
            for start in ("cold (empty cache)", "cached (second start)"):
                if log is not None:
                    print(f"  run {rep}: {start} ...", file=sys.stderr, flush=True)
                row = {"run": rep, "start": start, "settings": settings}
                row.update(run_start(script, cache, perf))
                rows.append(row)
            shutil.rmtree(cache, ignore_errors=True)
    if before is not None and _engine_cache_snapshot() != before:  # never the real cache
        raise RuntimeError("bench compile changed brush_env/engine/__pycache__")
    return rows


def summary(rows: list) -> dict:
    """Per start kind: median and spread ((max - min) / min) of CPU and instructions."""
    out = {}
    for start in dict.fromkeys(r["start"] for r in rows):
        sel = [r for r in rows if r["start"] == start]
        s = {}
        for key in ("wall_s", "cpu_s", "instructions"):
            vals = [r[key] for r in sel if r[key] is not None]
            if vals:
                s[key] = statistics.median(vals)
                s[key + "_spread"] = (max(vals) - min(vals)) / min(vals) if min(vals) else 0.0
        out[start] = s
    return out


def _fmt_s(v) -> str:
    return "n/a" if v is None else f"{v:.1f}"


def _fmt_instr(r: dict) -> str:
    return f"{r['instructions'] / 1e9:.2f}e9" if r["instructions"] is not None else "n/a"


TABLE = [
    ("run", lambda r: str(r["run"])),
    ("start", lambda r: r["start"]),
    ("wall [s]", lambda r: f"{r['wall_s']:.1f}"),
    ("warm_up() [s]", lambda r: f"{r['warmup_s']:.1f}"),
    ("CPU [s]", lambda r: f"{r['cpu_s']:.1f}"),
    ("warm_up() CPU [s]", lambda r: _fmt_s(r.get("warmup_cpu_s"))),
    ("of it LLVM [s]", lambda r: _fmt_s(r.get("llvm_s"))),
    ("of it numba's inlining [s]", lambda r: _fmt_s(r.get("inline_s"))),
    ("instructions:u", _fmt_instr),
    ("cache files", lambda r: str(r["cache_files"])),
    ("cache [kB]", lambda r: f"{r['cache_bytes'] / 1024:.0f}"),
    ("peak RSS [MB]", lambda r: f"{r['maxrss_mb']:.0f}"),
]


def format_report(rows: list) -> str:
    """The Markdown table and one summary line per start kind."""
    lines = [markdown_table(rows, TABLE), ""]
    if rows:
        lines.append(f"settings: {rows[0]['settings']}")
    for start, s in summary(rows).items():
        names = {"wall_s": "wall [s]", "cpu_s": "CPU [s]", "instructions": "instructions"}
        parts = [
            f"{name} {s[k]:.4g} (spread {100 * s[k + '_spread']:.1f} %)"
            for k, name in names.items()
            if k in s
        ]
        lines.append(f"{start}, median: " + ", ".join(parts))
    return "\n".join(lines)


def add_arguments(p) -> None:
    p.add_argument(
        "--json",
        action="store_true",
        help="one JSON object per start on stdout (machine info on stderr)",
    )
    p.add_argument(
        "--quick", action="store_true", help="one small kernel instead of the engine (for tests)"
    )
    p.add_argument(
        "--repeats",
        type=int,
        default=2,
        help="cold + cached start pairs, each with a new empty cache (default 2)",
    )
    p.add_argument("--no-perf", action="store_true", help="do not wrap the starts in perf stat")
    p.add_argument(
        "--level",
        default="all",
        help="kernel groups: all (brush-env warmup, default), default (brush-env reference's "
        "default set-up) or a fidelity level's (coarse, fast, reduced, balanced, paper, reference)",
    )


def bench_compile(args) -> int:
    """Measure the first-start compile and the cached start; print the table (or JSON rows)."""
    log = open_log(args)
    if args.level not in LEVEL_GROUPS:
        from ..engine.fidelity import load_fidelity

        load_fidelity(args.level)  # an unknown level: the loader's error, naming the levels
    rows = measure(
        args.repeats,
        quick=args.quick,
        perf=False if args.no_perf else None,
        log=log,
        level=args.level,
    )
    if args.json:
        for r in rows:
            print(json.dumps(r), flush=True)
        print(json.dumps({"summary": summary(rows)}), file=log)
    else:
        print(format_report(rows))
    return 0
