"""``bench fidelity``: every fidelity level (configs/fidelity) against ``reference``, in speed and
error (issue 12).

(a) **The paper's turn**: the ``bench contact`` motion (default brush on the flat plate, 3 mm
    press in 0.5 s, 0.25 s hold, one turn of the 20 mm circle at 20 mm/s; 7.234 s) at each
    level (its bodies, element, integrator, solver step and tip-tip solve; the step is the
    level's ``max_substep``; ``reference`` from the stored converged turn of ``bench element``
    unless ``--rerun-reference``).  RMS TCP-force error ``RMS_t |F - F_ref| / RMS_t |F_ref|`` and
    per-tip normal-force error ``RMS_{t,i} |f_i - f_i,ref| / RMS_{t,i} f_i,ref`` on a 5 ms grid,
    against the ``reference`` level run the same way; wall time per simulated second.
(b) **Random-policy episodes** of FlatPlate-v0 at each level (``gym.make(..., fidelity=level)``,
    every other env setting the default): ``--episodes`` episodes (seeds 0, 1, ...), each up to
    ``--steps`` env steps of actions uniform in [-1, 1]^6 from ``numpy.random.default_rng(seed)``
    -- the same actions at every level, so the TCP follows the same path until an episode ends.
    Errors over the steps both runs reached (TCP force and tip normal forces of the last engine
    step of each env step, pooled over episodes as in (a)); coverage difference = mean |final
    coverage - reference's| in points of the patch; env steps per second (one env, stepping
    only).

The table goes to stdout (``--json``: one object per level), the Pareto plot (x: wall per
simulated second of (a), log; y: RMS TCP-force error of (a) and (b)) to ``--plot`` (default
docs/figures/fidelity_pareto.png); ``--write`` stores each level's figures in the ``[measured]``
table of its configs/fidelity file.  The vectorised env (N = 16) of issue 12 is not built: no
column for it.

    brush-env bench fidelity [--episodes 20] [--steps 50] [--write] [--json] [--quick]
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from .contact import CONTACT_GRID_FULL, arc_seconds, simulate_contact, warm_kernels
from .harness import emit, machine_info, markdown_table, open_log

SAMPLE = 5e-3  # [s] comparison grid of (a)
ENV_ID = "brush_env/FlatPlate-v0"
PLOT = Path(__file__).resolve().parents[2] / "docs" / "figures" / "fidelity_pareto.png"


def turn_run(level, quick: bool = False) -> dict:
    """(a) for one level: times, TCP force and tip normal forces on the 5 ms grid, wall [s]."""
    from ..engine.fidelity import level_settings, load_fidelity

    fid = load_fidelity(level)
    # the level's own SimSettings, stepped at its solver step (no split)
    settings = level_settings(fid, dt=fid.max_substep)
    g = dict(CONTACT_GRID_FULL)
    press, hold, arc = (0.1, 0.0, 0.06) if quick else (g["press"], g["hold"], arc_seconds(g))
    ts, F, fn = [], [], []

    def observe(t, out):
        k = t / SAMPLE
        if abs(k - round(k)) < 1e-6:
            ts.append(t)
            F.append(out.tcp_force.copy())
            fn.append(out.tip_normal_force.copy())

    run = simulate_contact(
        settings.bodies_per_bristle,
        settings.dt,
        settings.integrator,
        True,
        press,
        hold,
        arc,
        observe=observe,
        sim_settings=settings,
    )
    return {
        "t": np.array(ts),
        "F": np.array(F),
        "fn": np.array(fn),
        "wall_s": run.wall,
        "sim_s": float(run.t[-1]),
        "status": run.status,
    }


def stored_reference_turn() -> dict:
    """(a) for ``reference`` from the stored converged turn (bench element's file: the same
    settings, TCP force every 1 ms; no tip forces, so no tip-force error against it)."""
    from .element import load_reference

    ref = load_reference()
    keep = np.abs(ref["t"] / SAMPLE - np.round(ref["t"] / SAMPLE)) < 1e-6
    return {
        "t": ref["t"][keep],
        "F": ref["F"][keep],
        "fn": None,
        "wall_s": float(ref.get("wall_s", math.nan)),
        "sim_s": float(ref["t"][-1]),
        "status": "ok (stored)",
    }


def episode_run(level, seed: int, steps: int, brush: str | None = None) -> dict:
    """(b) one random-policy episode at one level: per env step the TCP force, tip normal forces
    (last engine step), coverage; wall of the stepping [s]; how it ended."""
    import gymnasium as gym

    import brush_env  # noqa: F401  (registers the env ids)

    kw = {} if brush is None else {"brush": brush}
    env = gym.make(ENV_ID, fidelity=level, **kw)
    u = env.unwrapped
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    F, fn, cov = [], [], []
    end = "steps"
    t0 = time.perf_counter()
    for _ in range(steps):
        a = rng.uniform(-1.0, 1.0, env.action_space.shape).astype(np.float32)
        _, _, term, trunc, info = env.step(a)
        F.append(u._last.tcp_force.copy())
        fn.append(u._last.tip_normal_force.copy())
        cov.append(float(info["coverage"]))
        if term or trunc:
            end = info.get("termination") or "truncated"
            break
    wall = time.perf_counter() - t0
    env.close()
    return {
        "F": np.array(F),
        "fn": np.array(fn),
        "coverage": np.array(cov),
        "wall_s": wall,
        "end": end,
    }


def _pooled_error(pairs) -> float:
    """sqrt(sum |x - x_ref|^2 / sum |x_ref|^2) over (x, x_ref) pairs of equal shape."""
    num = sum(float(np.sum((x - r) ** 2)) for x, r in pairs)
    den = sum(float(np.sum(r**2)) for _, r in pairs)
    return math.sqrt(num / den) if den > 0 else math.nan


def compare_turn(run: dict, ref: dict) -> tuple[float, float]:
    """(TCP-force error, tip normal-force error) of (a) over the common samples."""
    common, i, j = np.intersect1d(
        np.round(run["t"] / SAMPLE).astype(int),
        np.round(ref["t"] / SAMPLE).astype(int),
        return_indices=True,
    )  # the same sample times (the stored reference starts at t = 0, a run at one step)
    force = _pooled_error([(run["F"][i], ref["F"][j])])
    tip = math.nan if ref["fn"] is None else _pooled_error([(run["fn"][i], ref["fn"][j])])
    return force, tip


def compare_episodes(eps: list, refs: list) -> tuple[float, float, float]:
    """(TCP-force error, tip normal-force error, mean |coverage difference| [points]) of (b)."""
    pf, pt, dc = [], [], []
    for e, r in zip(eps, refs):
        n = min(len(e["F"]), len(r["F"]))
        if n == 0:
            continue
        pf.append((e["F"][:n], r["F"][:n]))
        pt.append((e["fn"][:n], r["fn"][:n]))
        dc.append(100.0 * abs(e["coverage"][n - 1] - r["coverage"][n - 1]))
    return _pooled_error(pf), _pooled_error(pt), float(np.mean(dc)) if dc else math.nan


def bench_fidelity(args) -> int:
    """``brush-env bench fidelity`` (module docstring)."""
    from ..engine.fidelity import LEVELS, load_fidelity

    log = open_log(args)
    levels = list(args.levels or (("balanced", "fast") if args.quick else LEVELS))
    against = args.against or ("balanced" if args.quick else "reference")
    if against not in levels:
        levels.insert(0, against)
    episodes = 1 if args.quick else args.episodes
    steps = 3 if args.quick else args.steps
    brush = "tiny_env" if args.quick else None
    print("warming up the kernels ...", file=log, flush=True)
    warm_kernels()
    turns, eps = {}, {}
    for name in levels:
        print(f"  {name}: the paper's turn ...", file=log, flush=True)
        if name == "reference" and not args.quick and not args.rerun_reference:
            turns[name] = stored_reference_turn()
        else:
            turns[name] = turn_run(name, args.quick)
        print(f"  {name}: {episodes} random episodes ...", file=log, flush=True)
        eps[name] = [episode_run(name, s, steps, brush) for s in range(episodes)]
    rows = []
    for name in levels:
        fid = load_fidelity(name)
        tr = turns[name]
        ef, et = compare_turn(tr, turns[against]) if name != against else (0.0, 0.0)
        rf, rt, dc = (
            compare_episodes(eps[name], eps[against]) if name != against else (0.0, 0.0, 0.0)
        )
        n_steps = sum(len(e["F"]) for e in eps[name])
        wall = sum(e["wall_s"] for e in eps[name])
        rows.append(
            emit(
                args,
                {
                    "level": name,
                    "settings": fid.describe(),
                    "against": against,
                    "turn_rms_force_error": ef,
                    "turn_tip_force_error": et,
                    "turn_wall_per_sim_s": tr["wall_s"] / tr["sim_s"],
                    "turn_status": tr["status"],
                    "random_rms_force_error": rf,
                    "random_tip_force_error": rt,
                    "random_coverage_diff_points": dc,
                    "env_steps_per_s": n_steps / wall if wall > 0 else math.nan,
                    "episodes": len(eps[name]),
                    "env_steps": n_steps,
                    "episode_ends": [e["end"] for e in eps[name]],
                },
            )
        )
    if not args.json:
        print(format_table(rows))
    if args.plot and not args.quick:
        pareto_plot(rows, Path(args.plot))
        print(f"plot: {args.plot}", file=log)
    if args.write:
        info = machine_info()
        for r in rows:
            write_measured(load_fidelity(r["level"]).path, r, info)
        print("wrote [measured] into configs/fidelity/*.toml", file=log)
    return 0


def format_table(rows) -> str:
    pct = lambda x: "—" if not math.isfinite(x) else f"{100 * x:.1f} %"  # noqa: E731
    return markdown_table(
        rows,
        [
            ("level", lambda r: r["level"]),
            ("turn: TCP force err", lambda r: pct(r["turn_rms_force_error"])),
            ("turn: tip force err", lambda r: pct(r["turn_tip_force_error"])),
            ("wall / sim s", lambda r: f"{r['turn_wall_per_sim_s']:.2f}"),
            ("random: TCP force err", lambda r: pct(r["random_rms_force_error"])),
            ("random: tip force err", lambda r: pct(r["random_tip_force_error"])),
            ("coverage diff [points]", lambda r: f"{r['random_coverage_diff_points']:.2f}"),
            ("env steps/s (1 env)", lambda r: f"{r['env_steps_per_s']:.1f}"),
            ("settings", lambda r: r["settings"].split(": ", 1)[1]),
        ],
    )


def pareto_plot(rows, path: Path) -> None:
    """Force error [%] against wall per simulated second (log), both measures, one point per
    level and measure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for key, mark, label in (
        ("turn_rms_force_error", "o", "paper turn"),
        ("random_rms_force_error", "s", "random episodes"),
    ):
        xs = [r["turn_wall_per_sim_s"] for r in rows]
        ys = [100 * r[key] for r in rows]
        ax.scatter(xs, ys, marker=mark, label=label)
        for r, x, y in zip(rows, xs, ys):
            ax.annotate(r["level"], (x, y), textcoords="offset points", xytext=(5, 4), fontsize=8)
    ax.axhline(1.0, color="grey", lw=0.5, ls=":")
    ax.set_xscale("log")
    ax.set_xlabel("wall time per simulated second [s] (one core)")
    ax.set_ylabel(f"RMS TCP-force error vs {rows[0]['against']} [%]")
    ax.set_title("brush_env fidelity levels (brush-env bench fidelity)")
    ax.legend()
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_measured(path: Path, row: dict, info: dict) -> None:
    """Replace the ``[measured]`` table of a level's TOML file with ``row``'s figures."""
    from ..engine.fidelity import MEASURED_MARK

    text = path.read_text()
    head = text.split(MEASURED_MARK)[0].rstrip() + "\n\n"

    def num(x):
        return "nan" if not math.isfinite(x) else f"{x:.4g}"

    body = "\n".join(
        [
            MEASURED_MARK,
            "[measured]",
            f'against = "{row["against"]}"',
            f"turn_rms_force_error = {num(row['turn_rms_force_error'])}   # [-] paper turn",
            f"turn_tip_force_error = {num(row['turn_tip_force_error'])}   # [-]",
            f"turn_wall_per_sim_s = {num(row['turn_wall_per_sim_s'])}   # [s/s] one core",
            f"random_rms_force_error = {num(row['random_rms_force_error'])}   # [-]",
            f"random_tip_force_error = {num(row['random_tip_force_error'])}   # [-]",
            f"random_coverage_diff_points = {num(row['random_coverage_diff_points'])}",
            f"env_steps_per_s = {num(row['env_steps_per_s'])}   # one env, one core",
            f'commit = "{info.get("commit", "")}"',
            f'date = "{info.get("date", "")}"',
            f'cpu = "{info.get("cpu", "")}"',
        ]
    )
    path.write_text(head + body + "\n")


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per level on stdout (machine info on stderr)")
    add_flag(p, "--quick", "balanced against fast, a 0.16 s press, one 3-step episode (tests)")
    add_flag(p, "--write", "store each level's figures in its configs/fidelity file")
    p.add_argument("--episodes", type=int, default=20, help="random-policy episodes per level")
    p.add_argument("--steps", type=int, default=50, help="env steps per episode (at most)")
    p.add_argument("--levels", nargs="+", default=None, help="levels (default: all four)")
    p.add_argument("--against", default=None, help="the level the others are measured against")
    p.add_argument("--plot", default=str(PLOT), help="Pareto plot path ('' for none)")
    add_flag(
        p,
        "--rerun-reference",
        "run the reference level's turn (~10 min) instead of the stored converged turn "
        "(adds the tip-force error of (a))",
    )
