"""``brush-env bench cost``: what one bristle-step of the full chain costs, part by part, by
instruction counts under valgrind's callgrind, beside the arithmetic each part needs (issue 32,
item 1).

For each setting (``--bodies`` x ``--sweeps``: 3 and 6 mid-element bodies, one sweep and the
coupled solve, at 1 ms), ``bench steps``' motion on the plate (2 mm press, hold, one 18 mm
stroke: 1,589 steps of 1 ms, 40 bristles) runs twice: natively (the wall time of the measured
steps, and numba's cache compiled for valgrind's CPU) and under callgrind with the
instrumentation on for the measured steps only (``--window``: by default 300 steps from step 900,
mid-stroke, every tip sliding; the whole motion under callgrind takes ~1 h per setting at 6
bodies), writing where every engine kernel sits in memory (``--symbols``).  The call graph is
then split into parts by the kernels that are compiled as functions of their own:

* **Jacobian**: ``residual._jacobian_chain`` (the chain's blocks by forward differences: 13
  element evaluations per element; the inertia blocks), called when the factors are refreshed;
* **factorisation**: ``_kernels.block_factor_head`` (block Thomas, 6x6 blocks) and the tip
  block's ``lu6`` called by ``newton_solve`` itself (``residual.tip_refactor``);
* **solve**: ``_kernels.block_solve`` and ``lus6`` called by ``newton_solve``;
* **contact**: ``contact.tip_load`` (eq 6-10 and Table 3 at the tip, with its tangent);
* **shaft contact**: ``shaft.*`` called by ``newton_solve`` (every body's capsule against the
  surfaces, issue 28);
* **residual**: the element evaluations ``newton_solve`` makes itself (``_element_mid``,
  ``_element_paper`` and the libm calls under them);
* **predictor**: ``predict.*`` (the first guess) and ``_kernels.element_strain`` (the strain
  history's element strains).  Since 2026-12-06 ``predict._prepare`` is inlined into
  ``newton_solve``: its own arithmetic (momenta, rate history) and the extrapolation count in
  "Newton's own", only the strains here;
* **Newton's own**: the rest of ``newton_solve`` (inertia residual, the rotation update and its
  libm calls, line search, caps, convergence tests: inlined, so not separable);
* **coupling**: ``coupling.*`` (the coupled tip-tip solve, partner placement) and
  ``sweeps._partner_move``;
* **sweep and step**: the rest of ``step.step_bristles`` (sub-step halving, backups, predictors);
* **outside the bristle kernel**: everything outside ``step.step_bristles`` (the simulator's
  Python and its small kernels: the TCP wrench, the finite checks).

Per setting the table gives each part's instructions per bristle-step and per Newton iteration,
its share, and the wall time it stands for (the native loop's wall time times the share: an
estimate, as instructions do not cost equal time).  ``OPS`` holds the arithmetic each part needs
(floating-point operations, counted from the kernels' formulas, below), the limit the issue
compares against.

``--functions N`` adds, per setting, the N functions with the most instructions of their own
per bristle-step (compiled kernels by name, libm's and Python's as callgrind names them) and the
step kernel's and the broad phase's totals: where inside the parts the instructions go.

    brush-env bench cost [--bodies 3 6] [--sweeps 1 8] [--cache-dir DIR] [--keep DIR] [--json]
        [--functions N] [--from DIR]

Needs valgrind (callgrind_control); ~5-15 min per setting on this machine.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

from .harness import emit, markdown_table, open_log

#: floating-point operations of each part, per bristle of n bodies (counted from the kernels):
#: one mid element ~500 (relative rotation 45, its log and the half-turn exponential ~60 + 3
#: transcendental calls, chord and strain ~30, K (gs e + hs e_n) 90, the force and the moments
#: through T = R_A (I + exp(psi/2))^-1 R_A^T and J_l^-T ~250, carried to the centres 18); the
#: inertia residual (BDF2) ~50 per body; one 6x6 block of block Thomas: LU 144 + 6 right-hand
#: sides 432 + the Schur update 432; its solve ~220; the tip load (plane, eq 6-10) ~200.
ELEMENT_FLOPS = 500
OPS = {
    "residual": lambda n: n * (ELEMENT_FLOPS + 50),
    "Jacobian": lambda n: (13 * n - 6) * ELEMENT_FLOPS,  # forward differences, root one-sided
    "Jacobian, analytic (limit)": lambda n: n * 4 * ELEMENT_FLOPS,
    "factorisation": lambda n: n * 1008,
    "solve": lambda n: n * 220,
    "contact": lambda n: 200,
    "shaft contact": lambda n: n * 60,  # a capsule against the plate per body
    "predictor": lambda n: n * 60,  # extrapolated pose per body (2nd/3rd order)
}
#: the parts, in the table's order
PARTS = (
    "Jacobian",
    "factorisation",
    "solve",
    "contact",
    "shaft contact",
    "residual",
    "predictor",
    "Newton's own",
    "coupling",
    "sweep and step",
    "outside the bristle kernel",
)
_NAME = re.compile(r"(\d+)")


def short_name(mangled: str) -> str:
    """``module.function`` of a numba symbol (``_ZN9brush_env6engine6sweeps14sweep_bristlesB..``
    -> ``sweeps.sweep_bristles``); the symbol itself if it is not one."""
    start = mangled.find("_ZN")
    if start < 0:
        return mangled
    parts, i = [], start + 3
    while i < len(mangled) and mangled[i].isdigit():
        m = _NAME.match(mangled, i)
        k = int(m.group(1))
        j = m.end()
        parts.append(mangled[j : j + k])
        i = j + k
    parts = [p for p in parts if p not in ("brush_env", "engine")]
    # numba's C wrapper of an entry kernel (the call from Python) is "cfunc." + its symbol
    prefix = mangled[:start]
    return prefix + ".".join(parts[-2:]) if parts else mangled


def _elf_functions(obj: bytes) -> list[str]:
    """Names of the defined functions (STT_FUNC) of an ELF64 little-endian object file."""
    import struct

    if obj[:4] != b"\x7fELF" or obj[4] != 2 or obj[5] != 1:
        return []
    (shoff,) = struct.unpack_from("<Q", obj, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", obj, 0x3A)
    secs = [struct.unpack_from("<IIQQQQIIQQ", obj, shoff + i * shentsize) for i in range(shnum)]
    out = []
    for _name, typ, _fl, _addr, off, size, link, _info, _al, entsize in secs:
        if typ != 2 or entsize == 0:  # SHT_SYMTAB
            continue
        stroff = secs[link][4]
        for k in range(size // entsize):
            name, info, _o, shndx, _v, _s = struct.unpack_from("<IBBHQQ", obj, off + k * entsize)
            if info & 0xF == 2 and shndx != 0:
                end = obj.index(b"\0", stroff + name)
                out.append(obj[stroff + name : end].decode())
    return out


def kernel_symbols() -> dict[str, str]:
    """{hex address: ``module.function``} of every function in the engine's compiled kernels
    (each entry kernel's library holds the kernels it calls).  Names come from the library's
    LLVM module when it was compiled in this process, else from the object code in numba's cache
    file; addresses from the library itself."""
    import importlib
    import pkgutil

    from numba.core.registry import CPUDispatcher

    from .. import engine

    out: dict[str, str] = {}
    for m in pkgutil.iter_modules(engine.__path__):
        mod = importlib.import_module(f"{engine.__name__}.{m.name}")
        for d in vars(mod).values():
            if not isinstance(d, CPUDispatcher) or not d.overloads:
                continue
            cached: list[str] | None = None  # the cache file's names, read once per kernel
            for cres in d.overloads.values():
                fm = cres.library._final_module
                names = [f.name for f in fm.functions if not f.is_declaration] if fm else []
                if not names and d._cache is not None:
                    if cached is None:
                        cached = _cached_names(d)
                    names = cached
                for n in names:
                    try:
                        a = cres.library.get_pointer_to_function(n)
                    except Exception:  # noqa: BLE001 (a symbol of another library)
                        continue
                    if a:
                        out[hex(a)] = short_name(n)
    return out


def _cached_names(d) -> list[str]:
    """Function names in the object code of dispatcher d's cache file (numba keeps the code of
    a cache-loaded library as a loaded object, without its LLVM module)."""
    cf = d._cache._cache_file
    names: list[str] = []
    for data_name in cf._load_index().values():
        try:
            data = cf._load_data(data_name)
        except Exception:  # noqa: BLE001 (a stale entry)
            continue
        lib = data[0]
        for blob in lib[2] if len(lib) > 2 and isinstance(lib[2], tuple) else ():
            if isinstance(blob, (bytes, bytearray)):
                names += _elf_functions(bytes(blob))
    return names


def read_callgrind(path: str | Path) -> tuple[dict, dict]:
    """(self cost per function, inclusive cost per call arc (caller, callee)) [instructions] of a
    callgrind output file with the one event Ir; function names as callgrind wrote them (numba's
    code, which has no symbols for it, as ``0x...``)."""
    names: dict[str, str] = {}
    self_cost: dict[str, int] = defaultdict(int)
    arcs: dict[tuple[str, str], int] = defaultdict(int)
    fn = cfn = None
    in_call = False

    def name(spec: str) -> str:
        m = re.match(r"\((\d+)\)\s*(.*)", spec)
        if not m:
            return spec.strip()
        if m.group(2):
            names[m.group(1)] = m.group(2).strip()
        return names.get(m.group(1), spec)

    with open(path) as fh:
        for line in fh:
            if line.startswith("fn="):
                fn = name(line[3:])
            elif line.startswith("cfn="):
                cfn = name(line[4:])
            elif line.startswith("calls="):
                in_call = True
            elif line[:1].isdigit() or line[:1] in "+-*":
                tok = line.split()
                if len(tok) < 2 or fn is None:
                    continue
                cost = int(tok[1])
                if in_call:
                    arcs[(fn, cfn)] += cost
                    in_call = False
                else:
                    self_cost[fn] += cost
    return dict(self_cost), dict(arcs)


def _jit_name(raw: str, symbols: dict[str, str]) -> str:
    """callgrind's name of a JIT function (``0x00000000259b4ed0``) -> ``module.function``."""
    m = re.match(r"0x0*([0-9a-f]+)", raw)
    return symbols.get("0x" + m.group(1), raw) if m else raw


#: the step kernels (one sweep runs the first, more sweeps the second; one of them is called)
STEP_KERNELS = ("step.step_bristles", "step.step_bristles_coupled")

#: the part of a kernel called by newton_solve, by its name's ending or start (module docstring)
_CALLEE_PARTS = (
    (("_jacobian_chain", "residual.jacobian"), "Jacobian"),
    (("block_factor_head", "block_factor", ".lu6"), "factorisation"),
    (("block_solve", ".lus6"), "solve"),
    (("contact.tip_load",), "contact"),
    (("_element_mid", "_element_paper"), "residual"),
)


def _part_of(callee: str) -> str | None:
    for ends, part in _CALLEE_PARTS:
        if callee.endswith(ends):
            return part
    if callee.startswith("shaft."):
        return "shaft contact"
    if callee.startswith("predict.") or callee.endswith("element_strain"):
        return "predictor"
    return None


def _is_coupling(f: str) -> bool:
    return f.startswith("coupling.") or f == "sweeps._partner_move"


def split(self_cost: dict, arcs: dict, symbols: dict[str, str]) -> dict[str, int]:
    """Instructions per part (module docstring) of one callgrind run."""
    sc: dict[str, int] = defaultdict(int)
    ar: dict[tuple[str, str], int] = defaultdict(int)
    for f, c in self_cost.items():
        sc[_jit_name(f, symbols)] += c
    for (f, g), c in arcs.items():
        ar[(_jit_name(f, symbols), _jit_name(g, symbols))] += c
    callees: dict[str, dict[str, int]] = defaultdict(dict)
    for (f, g), c in ar.items():
        callees[f][g] = callees[f].get(g, 0) + c

    def incl(f: str) -> int:
        return sc.get(f, 0) + sum(c for g, c in callees.get(f, {}).items() if g != f)

    total = sum(sc.values())
    # one sweep runs step_bristles, more sweeps step_bristles_coupled (one of them is called)
    step = sum(incl(k) for k in STEP_KERNELS)
    newton = incl("newton.newton_solve")
    out = dict.fromkeys(PARTS, 0)
    named = 0  # what newton_solve's named callees take
    for g, c in callees.get("newton.newton_solve", {}).items():
        part = _part_of(g)
        if part is not None:
            out[part] += c
            named += c
    out["Newton's own"] = newton - named
    coupling = sum(incl(f) for f in sc if _is_coupling(f))
    # calls from one coupling kernel into another are counted once: only arcs from outside
    coupling -= sum(c for (f, g), c in ar.items() if _is_coupling(f) and _is_coupling(g))
    out["coupling"] = coupling
    out["sweep and step"] = step - newton - coupling
    out["outside the bristle kernel"] = total - step
    return out


def functions(self_cost: dict, arcs: dict, symbols: dict[str, str]) -> dict[str, dict[str, int]]:
    """Per function (compiled kernels by ``module.function``, libm and Python by callgrind's
    name): its own instructions ("self") and with its callees ("inclusive")."""
    sc: dict[str, int] = defaultdict(int)
    inc: dict[str, int] = defaultdict(int)
    for f, c in self_cost.items():
        sc[_jit_name(f, symbols)] += c
    for f, c in sc.items():
        inc[f] += c
    for (f, g), c in arcs.items():
        f, g = _jit_name(f, symbols), _jit_name(g, symbols)
        if f != g:
            inc[f] += c
    return {f: {"self": sc.get(f, 0), "inclusive": inc[f]} for f in inc}


def function_rows(r: dict, nb: int, top: int) -> list[dict]:
    """One setting's ``top`` functions by their own instructions per bristle-step, after two
    rows for the compiled step: the step kernel (``step.step_bristles`` or its coupled twin)
    and the shaft's broad phase, inclusive."""
    bsteps = r["steps"] * nb
    fn = r["functions"]
    setting = f"{r['bodies']} bodies, " + ("one sweep" if r["sweeps"] == 1 else "coupled")

    def row(name, self_c, inc_c):
        return {
            "setting": setting,
            "function": name,
            "self_per_bristle_step": self_c / bsteps,
            "inclusive_per_bristle_step": inc_c / bsteps,
        }

    step = sum(fn.get(k, {}).get("inclusive", 0) for k in STEP_KERNELS)
    broad = fn.get("shaft.broad_phase", {}).get("inclusive", 0)
    rows = [row("the step kernel (inclusive)", 0, step), row("broad phase (inclusive)", 0, broad)]
    ranked = sorted(fn.items(), key=lambda kv: -kv[1]["self"])[:top]
    return rows + [row(k, v["self"], v["inclusive"]) for k, v in ranked]


def _valgrind_cpu() -> tuple[str, str]:
    code = (
        "import llvmlite.binding as b; print(b.get_host_cpu_name()); "
        "print(b.get_host_cpu_features().flatten())"
    )
    r = subprocess.run(
        ["valgrind", "-q", sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    name, feats = r.stdout.strip().splitlines()[-2:]
    return name, feats


def _run_setting(
    bodies: int, sweeps: int, env: dict, keep: Path, window, motion: str = "scrub"
) -> dict:
    steps = [sys.executable, "-m", "brush_env.cli", "bench", "steps", "--scene", "flat_plate"]
    steps += ["--motion", motion]
    steps += ["--fidelity", "balanced", "--bodies", str(bodies), "--sweeps", str(sweeps)]
    steps += ["--json"]
    if window:
        steps += ["--window", str(window[0]), str(window[1])]
    native = subprocess.run(steps, env=env, capture_output=True, text=True, check=True)
    row = json.loads(native.stdout.strip().splitlines()[-1])
    out = keep / f"callgrind_{bodies}_{sweeps}.out"
    sym = keep / f"symbols_{bodies}_{sweeps}.json"
    vg = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
    vg += ["--collect-atstart=yes", "--instr-atstart=no"]
    subprocess.run(
        vg + steps + ["--callgrind", "--symbols", str(sym)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    (keep / f"native_{bodies}_{sweeps}.json").write_text(json.dumps(row))
    return _from_files(bodies, sweeps, keep)


def _from_files(bodies: int, sweeps: int, keep: Path) -> dict:
    """One setting's row from its files in ``keep`` (the native run's row, callgrind's output and
    the symbol map)."""
    row = json.loads((keep / f"native_{bodies}_{sweeps}.json").read_text())
    self_cost, arcs = read_callgrind(keep / f"callgrind_{bodies}_{sweeps}.out")
    symbols = json.loads((keep / f"symbols_{bodies}_{sweeps}.json").read_text())
    parts = split(self_cost, arcs, symbols)
    fn = functions(self_cost, arcs, symbols)
    return {"bodies": bodies, "sweeps": sweeps, **row, "parts": parts, "functions": fn}


def table_rows(r: dict, nb: int) -> list[dict]:
    """One setting's rows: per part its instructions per bristle-step and per Newton iteration,
    share and wall time it stands for, and the part's arithmetic (OPS) per Newton iteration."""
    bsteps = r["steps"] * nb
    total = sum(r["parts"].values())
    rows = []
    setting = f"{r['bodies']} bodies, " + ("one sweep" if r["sweeps"] == 1 else "coupled")
    for p in PARTS:
        c = r["parts"][p]
        ops = OPS.get(p)
        rows.append(
            {
                "setting": setting,
                "part": p,
                "instr_per_bristle_step": c / bsteps,
                "instr_per_iteration": c / max(r["newton_iterations"], 1),
                "share": c / total if total else 0.0,
                "wall_us_per_bristle_step": 1e6 * r["wall_s"] * (c / total) / bsteps,
                "flops_per_call": ops(r["bodies"]) if ops else None,
            }
        )
    return rows


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per setting on stdout (machine info on stderr)")
    p.add_argument("--bodies", type=int, nargs="+", default=[3, 6], help="bodies (3 6)")
    p.add_argument("--sweeps", type=int, nargs="+", default=[1, 8], help="tip-tip sweeps (1 8)")
    p.add_argument(
        "--cache-dir",
        default=str(Path.home() / ".cache" / "brush_env" / "numba-valgrind"),
        help="numba cache compiled for valgrind's CPU (kept between runs)",
    )
    p.add_argument("--keep", default=None, help="keep callgrind's files in this folder")
    p.add_argument(
        "--functions",
        type=int,
        default=0,
        metavar="N",
        help="also a table of the N functions with the most own instructions per bristle-step "
        "(and the step kernel's and the broad phase's inclusive totals)",
    )
    p.add_argument(
        "--from",
        dest="from_dir",
        default=None,
        help="no runs: split the files a run kept (--keep DIR) again",
    )
    p.add_argument(
        "--motion",
        choices=("scrub", "turn"),
        default="scrub",
        help="bench steps' motion: scrub (press and one stroke, no tip-tip contact) or turn (the "
        "paper turn, where the coupled tip-tip solve works; e.g. --window 4000 100)",
    )
    p.add_argument(
        "--window",
        type=int,
        nargs=2,
        default=[900, 300],
        metavar=("START", "COUNT"),
        help="the steps measured (default 900 300: mid-stroke, every tip sliding on the plate; "
        "0 0 for the whole motion)",
    )


def bench_cost(args) -> int:
    """``brush-env bench cost``: see the module docstring."""
    log = open_log(args)
    rows: list[dict] = []
    frows: list[dict] = []
    if args.from_dir:
        for bodies in args.bodies:
            for sweeps in args.sweeps:
                r = emit(args, _from_files(bodies, sweeps, Path(args.from_dir)))
                rows += table_rows(r, r["bristles"])
                frows += function_rows(r, r["bristles"], args.functions) if args.functions else []
        return _print(args, rows, frows)
    name, feats = _valgrind_cpu()
    env = dict(os.environ)
    env.update(NUMBA_CPU_NAME=name, NUMBA_CPU_FEATURES=feats, NUMBA_CACHE_DIR=args.cache_dir)
    keep = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="brush_cost_"))
    keep.mkdir(parents=True, exist_ok=True)
    for bodies in args.bodies:
        for sweeps in args.sweeps:
            print(f"{bodies} bodies, {sweeps} sweep(s): native, then callgrind ...", file=log)
            window = None if args.window == [0, 0] else args.window
            r = emit(args, _run_setting(bodies, sweeps, env, keep, window, args.motion))
            rows += table_rows(r, r["bristles"])
            frows += function_rows(r, r["bristles"], args.functions) if args.functions else []
    return _print(args, rows, frows)


def _print(args, rows: list[dict], frows: list[dict]) -> int:
    if not args.json and frows:
        fcols = [
            ("setting", lambda r: r["setting"]),
            ("function", lambda r: r["function"]),
            ("own instr. / bristle-step", lambda r: f"{r['self_per_bristle_step']:,.0f}"),
            ("with callees", lambda r: f"{r['inclusive_per_bristle_step']:,.0f}"),
        ]
        print(markdown_table(frows, fcols))
        print()
    if not args.json:
        cols = [
            ("setting", lambda r: r["setting"]),
            ("part", lambda r: r["part"]),
            ("instr. / bristle-step", lambda r: f"{r['instr_per_bristle_step']:,.0f}"),
            ("instr. / iteration", lambda r: f"{r['instr_per_iteration']:,.0f}"),
            ("share", lambda r: f"{100 * r['share']:.1f} %"),
            ("~µs / bristle-step", lambda r: f"{r['wall_us_per_bristle_step']:.2f}"),
            (
                "flops per call (arithmetic)",
                lambda r: "" if r["flops_per_call"] is None else f"{r['flops_per_call']:,}",
            ),
        ]
        print(markdown_table(rows, cols))
    return 0
