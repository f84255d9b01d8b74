"""``bench fidelity``: every fidelity level (configs/fidelity) against ``reference``, in speed and
error (issues 12 and 29).

(a) **The paper's turn**: the ``bench contact`` motion (default brush on the flat plate, 3 mm
    press in 0.5 s, 0.25 s hold, one turn of the 20 mm circle at 20 mm/s; 7.234 s) at each
    level (its bodies, element, integrator, solver step and tip-tip solve; the step is the
    level's ``max_substep``).  Each run records, at every solver step, the TCP force, the tips'
    normal forces and their contact and sliding flags, and the tip nodes at the end of the hold;
    forces are compared on a 5 ms grid (a run stepped at a step that does not divide 5 ms is
    interpolated linearly onto it).  ``reference`` comes from its stored turn
    (``REFERENCE_TURN_FILE``, ``--write-reference turn`` remakes it; without it, bench element's
    TCP-force-only file, and the tip measures are "—") unless ``--rerun-reference``.
    Measures against ``reference`` (definitions: ``fidelity_metrics``): RMS TCP-force error,
    the same outside +-10 ms of the reference's stick->slip events (those after >= 5 ms of
    stick), phase means of |F| (press, hold, sliding) and their relative errors, the event-time
    error (median and largest |dt| of each reference event to the same bristle's nearest event,
    unmatched beyond 100 ms), the
    bristles on the reference's buckling side at the end of the hold, the per-tip normal-force
    error; wall time per simulated second.
(b) **Random-policy episodes** of FlatPlate-v0 at each level (``gym.make(..., fidelity=level)``,
    every other env setting the default): ``--episodes`` episodes (seeds 0, 1, ...), each up to
    ``--steps`` env steps of actions uniform in [-1, 1]^6 from ``numpy.random.default_rng(seed)``
    -- the same actions at every level, so the TCP follows the same path until an episode ends.
    Errors over the steps both runs reached (TCP force and tip normal forces of the last engine
    step of each env step, pooled over episodes as in (a)); coverage difference = mean |final
    coverage - reference's| in points of the patch; env steps per second (one env, stepping
    only, observation and reward included).  The reference level's episodes are read from
    ``REFERENCE_EPISODES_FILE`` when it holds that level, those seeds and at least those steps
    (``--write-reference episodes`` remakes it; its env steps/s is the stored run's).
(c) **Batched env steps per second**: ``gym.make_vec(ENV_ID, num_envs=N,
    vectorization_mode="vector_entry_point", fidelity=level)`` for N in ``--vec-sizes`` (16,
    64), reset with seed 0, one untimed step, then steps of random actions from
    ``default_rng(0)`` until ``--vec-seconds`` of wall have passed (at most ``--vec-steps``);
    rate = N x steps / wall.  The batched env (brush_env/envs/vector.py) is today a Python loop
    over N single-env cores, so its rate is about the single env's; a level is measured only
    where one warm-up and one timed batched step fit in ``--vec-seconds`` at its single-env rate
    of (b) (``batched_too_slow``: in practice ``fast`` and ``reduced``).  "n/a" (NaN in JSON and
    [measured]) where it is too slow or ``make_vec`` raises, with the reason in ``vec_note``.

The tables go to stdout (``--json``: one object per level), the Pareto plot (x: wall per
simulated second of (a), log; y: the error measures) to ``--plot`` (default
docs/figures/fidelity_pareto.png); ``--write`` stores each level's figures in the ``[measured]``
table of its configs/fidelity file.

    brush-env bench fidelity [--episodes 20] [--steps 100] [--write] [--json] [--quick]
    brush-env bench fidelity --write-reference turn|episodes|all [--levels reference]
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import fidelity_metrics as fm
from .contact import CONTACT_GRID_FULL, arc_seconds, simulate_contact, warm_kernels
from .harness import emit, machine_info, markdown_table, open_log

SAMPLE = 5e-3  # [s] comparison grid of (a)
ENV_ID = "brush_env/FlatPlate-v0"
ROOT = Path(__file__).resolve().parents[2]
PLOT = ROOT / "docs" / "figures" / "fidelity_pareto.png"
#: the reference level's turn with its tips (5 ms grid; bench element's file has the TCP only)
REFERENCE_TURN_FILE = ROOT / "tests" / "data" / "flat_plate_turn_reference_tips.npz"
#: the reference level's random-policy episodes (seeds 0.., per env step)
REFERENCE_EPISODES_FILE = ROOT / "tests" / "data" / "flat_plate_random_episodes_reference.npz"
#: (a)'s phases: name -> (start, end) [s] of the full turn (the end is the run's last sample)
PHASE_NAMES = ("press", "hold", "sliding")
VEC_SIZES = (16, 64)


def _turn_motion(quick: bool) -> tuple[float, float, float]:
    """(press, hold, arc) [s] of (a): the paper's turn, or a 0.1 s press and 0.06 s of circle."""
    g = dict(CONTACT_GRID_FULL)
    return (0.1, 0.0, 0.06) if quick else (g["press"], g["hold"], arc_seconds(g))


def _hold_geometry(settings, press: float, hold: float, t: float) -> tuple[np.ndarray, np.ndarray]:
    """(rest tip nodes [mm] (nb, 3), thickness directions (nb, 3)) in the world at time ``t``
    [s] of the turn: where the straight unloaded bristles' tips would be at the TCP's pose then,
    and each root frame's local z turned by the TCP rotation (scene and trajectory built as
    ``contact.simulate_contact`` builds them)."""
    from ..engine import Simulator, load_scene
    from ..experiments.plan import plate_height
    from ..motion import R0
    from .contact import press_and_circle

    scene = load_scene("flat_plate")
    scene = replace(scene, brush=scene.brush.with_bodies(settings.bodies_per_bristle))
    sim = Simulator(scene, settings)
    traj, _ = press_and_circle(sim.touch_height(R0, plate_height(scene)), press, hold)
    P, R, _, _ = traj.sample(np.array([t]))
    rest = P[0] + sim.rest_tips() @ R[0].T
    lateral = sim.model.root_R[:, :, 2] @ R[0].T
    return rest, lateral


def turn_run(level, quick: bool = False) -> dict:
    """(a) for one level (``turn_summary`` of its run): the 5 ms grid's times [s], TCP force
    [N], tip normal forces [N], sliding and contact flags; the stick->slip events at the solver
    step; the tips' lateral offsets [mm] at the end of the hold; phases; wall [s]."""
    from ..engine.fidelity import level_settings, load_fidelity

    fid = load_fidelity(level)
    # the level's own SimSettings, stepped at its solver step (no split)
    settings = level_settings(fid, dt=fid.max_substep)
    press, hold, arc = _turn_motion(quick)
    t_hold = press + hold
    rec: dict = {"t": [], "F": [], "fn": [], "slide": [], "contact": [], "tips": None}

    def observe(t, out):
        rec["t"].append(t)
        rec["F"].append(out.tcp_force.copy())
        rec["fn"].append(out.tip_normal_force.copy())
        rec["slide"].append(out.tip_sliding.copy())
        rec["contact"].append(out.tip_in_contact.copy())
        if t <= t_hold + 1e-9:
            rec["tips"] = (t, out.tip_pos.copy(), out.tip_tangential_force.copy())

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
    offsets = lateral_force = None
    if rec["tips"] is not None:
        t_tips, tips, tangential = rec["tips"]
        rest, lateral = _hold_geometry(settings, press, hold, t_tips)
        offsets = fm.lateral_offsets(tips, rest, lateral)
        lateral_force = fm.components_along(tangential, lateral)
    return turn_summary(
        np.array(rec["t"]),
        np.array(rec["F"]).reshape(-1, 3),
        np.array(rec["fn"]),
        np.array(rec["slide"], bool),
        np.array(rec["contact"], bool),
        offsets,
        lateral_force,
        phases=turn_phases(press, hold, press + hold + arc),
        wall_s=run.wall,
        status=run.status,
    )


def turn_phases(press: float, hold: float, end: float) -> dict:
    """The paper turn's phases [s]: press, hold, sliding (shared with `bench coupled`)."""
    return {"press": (0.0, press), "hold": (press, press + hold), "sliding": (press + hold, end)}


def turn_summary(
    t, F, fn, sliding, contact, offsets, lateral_force, phases, wall_s, status
) -> dict:
    """A turn run's record reduced to what (a) compares: every solver step's flags become the
    stick->slip events (``fidelity_metrics.stick_slip_events``), forces and flags go onto the
    5 ms grid (multiples of SAMPLE from the first step to the last), the phase means of |F|
    on it (a run that diverged in its first step has one sample of NaN at the first step)."""
    if len(t) == 0:
        nb = np.shape(fn)[1] if np.ndim(fn) == 2 else 0
        t = np.array([SAMPLE])
        F, fn = np.full((1, 3), np.nan), np.full((1, nb), np.nan)
        sliding = contact = np.zeros((1, nb), bool)
    grid = np.arange(1, int(math.floor(t[-1] / SAMPLE + 1e-6)) + 1) * SAMPLE
    grid = grid[grid >= t[0] - 1e-9]
    idx = np.clip(np.searchsorted(t, grid - 1e-9), 0, max(len(t) - 1, 0))
    events = fm.stick_slip_events(t, sliding, contact)
    Fg = fm.on_grid(grid, t, F)
    return {
        "t": grid,
        "F": Fg,
        "fn": fm.on_grid(grid, t, fn),
        "sliding": sliding[idx],
        "in_contact": contact[idx],
        "events": events,
        "offsets": offsets,
        "lateral_force": lateral_force,
        "phases": phases,
        "phase_means": fm.phase_means(grid, Fg, phases),
        "wall_s": wall_s,
        "sim_s": float(t[-1]),
        "status": status,
    }


def write_reference_turn(level: str = "reference", path: Path = REFERENCE_TURN_FILE) -> dict:
    """Run (a) at ``level`` (the full turn) and store it (``save_turn``)."""
    from ..engine.fidelity import load_fidelity

    run = turn_run(level)
    if run["status"] != "ok":
        raise RuntimeError(f"the {level} turn did not finish: {run['status']}")
    save_turn(path, run, level, load_fidelity(level).describe())
    return load_reference_turn(path)


def save_turn(path: Path, run: dict, level: str, settings: str) -> None:
    """Store a ``turn_run`` record, compressed: the 5 ms grid's t [s], F [N], fn [N] (float32),
    sliding and contact flags, the events (bristle, t [s]) at the solver step, the lateral
    offsets [mm] at the end of the hold, the phases [s], wall [s] and the level, its settings,
    machine and commit."""
    motion = "bench contact (full): press 0.5 s, hold 0.25 s, one turn"
    meta = dict(level=level, settings=settings, motion=motion, **machine_info())
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path,
        t=run["t"],
        F=run["F"],
        fn=run["fn"].astype(np.float32),
        sliding=run["sliding"],
        in_contact=run["in_contact"],
        event_bristle=run["events"][0],
        event_t=run["events"][1],
        event_stick_s=run["events"][2],
        offsets=run["offsets"],
        lateral_force=run["lateral_force"],
        phases=np.array([run["phases"][k] for k in PHASE_NAMES]),
        wall_s=run["wall_s"],
        meta=json.dumps(meta),
    )


def load_reference_turn(path: Path = REFERENCE_TURN_FILE) -> dict:
    """The stored turn of ``write_reference_turn`` in ``turn_run``'s form (``meta``: its level,
    settings, machine, commit)."""
    d = np.load(path, allow_pickle=False)
    phases = {k: (float(a), float(b)) for k, (a, b) in zip(PHASE_NAMES, d["phases"])}
    meta = json.loads(str(d["meta"]))
    return {
        "t": d["t"],
        "F": d["F"],
        "fn": d["fn"].astype(float),
        "sliding": d["sliding"],
        "in_contact": d["in_contact"],
        "events": (d["event_bristle"], d["event_t"], d["event_stick_s"]),
        "offsets": d["offsets"],
        "lateral_force": d["lateral_force"],
        "phases": phases,
        "phase_means": fm.phase_means(d["t"], d["F"], phases),
        "wall_s": float(d["wall_s"]),
        "sim_s": float(d["t"][-1]),
        "status": f"ok (stored {meta.get('date', '')})",
        "meta": meta,
    }


def stored_reference_turn(level: str = "reference") -> dict:
    """(a) for ``level`` from storage: ``REFERENCE_TURN_FILE`` if it holds that level, else (for
    ``reference``) bench element's converged turn (the same settings, TCP force every 1 ms; no
    tips: the tip measures are NaN against it)."""
    if REFERENCE_TURN_FILE.exists():
        ref = load_reference_turn()
        if ref["meta"].get("level") == level:
            return ref
    if level != "reference":
        raise FileNotFoundError(f"no stored turn of level {level!r}")
    from .element import load_reference

    ref = load_reference()
    keep = np.abs(ref["t"] / SAMPLE - np.round(ref["t"] / SAMPLE)) < 1e-6
    phases = turn_phases(*_turn_motion(False)[:2], float(ref["t"][-1]))
    return {
        "t": ref["t"][keep],
        "F": ref["F"][keep],
        "fn": None,
        "sliding": None,
        "in_contact": None,
        "events": None,
        "offsets": None,
        "lateral_force": None,
        "phases": phases,
        "phase_means": fm.phase_means(ref["t"][keep], ref["F"][keep], phases),
        "wall_s": float(ref.get("wall_s", math.nan)),
        "sim_s": float(ref["t"][-1]),
        "status": "ok (stored, TCP force only)",
    }


def episode_run(level, seed: int, steps: int, brush: str | None = None) -> dict:
    """(b) one random-policy episode at one level: per env step the TCP force [N], tip normal
    forces [N] (last engine step), coverage [0-1]; wall of the stepping [s]; how it ended."""
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


def write_reference_episodes(
    level: str, episodes: int, steps: int, path: Path = REFERENCE_EPISODES_FILE, log=None
) -> list:
    """Run (b) at ``level`` (seeds 0 .. episodes-1, up to ``steps`` env steps) and store it
    (``save_episodes``).  Returns the episodes."""
    from ..engine.fidelity import load_fidelity

    eps = []
    for s in range(episodes):
        eps.append(episode_run(level, s, steps))
        if log is not None:
            e = eps[-1]
            print(f"    seed {s}: {len(e['F'])} steps in {e['wall_s']:.1f} s", file=log, flush=True)
    save_episodes(path, eps, level, load_fidelity(level).describe(), steps)
    return eps


def save_episodes(path: Path, eps: list, level: str, settings: str, steps: int) -> None:
    """Store ``episode_run`` records (seeds 0, 1, ...), compressed: per episode its length, F
    [N], fn [N] (float32), coverage [0-1] (NaN beyond its end), wall [s] and end; the level, its
    settings, the steps asked, machine and commit."""
    nb = eps[0]["fn"].shape[1]
    F = np.full((len(eps), steps, 3), np.nan)
    fn = np.full((len(eps), steps, nb), np.nan, np.float32)
    cov = np.full((len(eps), steps), np.nan)
    for k, e in enumerate(eps):
        n = len(e["F"])
        F[k, :n], fn[k, :n], cov[k, :n] = e["F"], e["fn"], e["coverage"]
    meta = dict(
        level=level,
        settings=settings,
        episodes=len(eps),
        steps=steps,
        env=ENV_ID,
        ends=[e["end"] for e in eps],
        **machine_info(),
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path,
        n=np.array([len(e["F"]) for e in eps]),
        F=F,
        fn=fn,
        coverage=cov,
        wall_s=np.array([e["wall_s"] for e in eps]),
        meta=json.dumps(meta),
    )


def load_reference_episodes(
    level: str, episodes: int, steps: int, path: Path = REFERENCE_EPISODES_FILE
) -> list | None:
    """The stored episodes of ``level`` (seeds 0 .. episodes-1, cut to ``steps``), or None if
    the file is missing or holds another level, fewer episodes or shorter unfinished ones.  Each
    episode's wall is the stored one, scaled by the share of its steps kept."""
    if not path.exists():
        return None
    d = np.load(path, allow_pickle=False)
    meta = json.loads(str(d["meta"]))
    if meta.get("level") != level or meta["episodes"] < episodes or meta["steps"] < steps:
        return None
    eps = []
    for k in range(episodes):
        n_all = int(d["n"][k])
        n = min(n_all, steps)
        eps.append(
            {
                "F": d["F"][k, :n],
                "fn": d["fn"][k, :n].astype(float),
                "coverage": d["coverage"][k, :n],
                "wall_s": float(d["wall_s"][k]) * n / max(n_all, 1),
                "end": meta["ends"][k] if n == n_all else "steps",
                "stored": f"{meta.get('commit', '')}, {meta.get('date', '')}",
            }
        )
    return eps


def vector_steps_per_s(
    level, n: int, seconds: float = 10.0, max_steps: int = 200, seed: int = 0
) -> tuple[float, str]:
    """(c): (env steps per second of the batched env [1/s], note) -- NaN and the error's first
    line if ``gym.make_vec`` (or its first step) raises."""
    import gymnasium as gym

    import brush_env  # noqa: F401  (registers the env ids)

    try:
        envs = gym.make_vec(
            ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", fidelity=level
        )
    except Exception as e:  # noqa: BLE001  (anything: the batched env is not there)
        return math.nan, f"n/a: {type(e).__name__}: {str(e).splitlines()[0][:120]}"
    try:
        rng = np.random.default_rng(seed)
        shape = envs.action_space.shape
        envs.reset(seed=seed)
        envs.step(rng.uniform(-1.0, 1.0, shape).astype(np.float32))  # compile / warm
        k = 0
        t0 = time.perf_counter()
        while k < max_steps:
            envs.step(rng.uniform(-1.0, 1.0, shape).astype(np.float32))
            k += 1
            if time.perf_counter() - t0 >= seconds:
                break
        wall = time.perf_counter() - t0
    except Exception as e:  # noqa: BLE001
        return math.nan, f"n/a: step raised {type(e).__name__}: {str(e).splitlines()[0][:120]}"
    finally:
        envs.close()
    return n * k / wall, f"{k} steps of {n} envs in {wall:.1f} s"


def compare_turn(run: dict, ref: dict) -> tuple[float, float]:
    """(TCP-force error, tip normal-force error) [-] of (a) over the common 5 ms samples."""
    i, j = _common(run, ref)
    force = fm.pooled_rms_error([(run["F"][i], ref["F"][j])])
    tip = math.nan if ref["fn"] is None else fm.pooled_rms_error([(run["fn"][i], ref["fn"][j])])
    return force, tip


def _common(run: dict, ref: dict) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the grid samples both runs have (the same times)."""
    _, i, j = np.intersect1d(
        np.round(run["t"] / SAMPLE).astype(int),
        np.round(ref["t"] / SAMPLE).astype(int),
        return_indices=True,
    )
    return i, j


def turn_metrics(run: dict, ref: dict) -> dict:
    """Every measure of (a) of ``run`` against ``ref`` (module docstring; definitions in
    ``fidelity_metrics``), as row keys."""
    force, tip = compare_turn(run, ref)
    out: dict = {"turn_rms_force_error": force, "turn_tip_force_error": tip}
    pm = run["phase_means"]
    perr = fm.phase_mean_errors(pm, ref["phase_means"])
    for k in PHASE_NAMES:
        out[f"turn_phase_mean_{k}_N"] = pm[k]
        out[f"turn_phase_err_{k}"] = perr[k]
    nan = math.nan
    out.update(
        turn_rms_error_outside_events=nan,
        turn_masked_fraction=nan,
        event_dt_median_ms=nan,
        event_dt_max_ms=nan,
        events_ref=0,
        events_matched=0,
        events_unmatched=0,
        events_run=0,
        buckling_same_side=-1,
        lateral_force_same_side=-1,
        bristles=0,
    )
    if ref["events"] is not None:
        ref_ev = fm.long_stick_events(ref["events"])
        run_ev = fm.long_stick_events(run["events"])
        i, j = _common(run, ref)
        mask = fm.event_mask(ref["t"][j], ref_ev[1], fm.EVENT_HALF_WIDTH)
        out["turn_rms_error_outside_events"] = fm.rms_error_outside(run["F"][i], ref["F"][j], mask)
        out["turn_masked_fraction"] = float(mask.mean()) if mask.size else nan
        # only the reference's events up to where the run got
        reached = ref_ev[1] <= run["sim_s"] + 1e-9
        m = fm.match_events((ref_ev[0][reached], ref_ev[1][reached]), run_ev)
        out.update(
            event_dt_median_ms=m["median_abs_ms"],
            event_dt_max_ms=m["max_abs_ms"],
            event_dt_signed_median_ms=m["median_ms"],
            events_ref=m["n_ref"],
            events_matched=m["n_matched"],
            events_unmatched=m["n_unmatched"],
            events_run=m["n_run"],
            transitions_ref=int(len(ref["events"][0])),
            transitions_run=int(len(run["events"][0])),
        )
    if ref["offsets"] is not None and run["offsets"] is not None:
        out["buckling_same_side"] = fm.same_side_count(
            fm.buckling_sides(run["offsets"]), fm.buckling_sides(ref["offsets"])
        )
        out["bristles"] = int(len(ref["offsets"]))
    if ref["lateral_force"] is not None and run["lateral_force"] is not None:
        out["lateral_force_same_side"] = fm.same_side_count(
            fm.buckling_sides(run["lateral_force"], fm.SIDE_FORCE_TOL),
            fm.buckling_sides(ref["lateral_force"], fm.SIDE_FORCE_TOL),
        )
    return out


def bench_fidelity(args) -> int:
    """``brush-env bench fidelity`` (module docstring)."""
    from ..engine.fidelity import LEVELS, load_fidelity

    log = open_log(args)
    levels = list(args.levels or (("balanced", "fast") if args.quick else LEVELS))
    against = args.against or ("balanced" if args.quick else "reference")
    if args.write_reference:
        return _write_references(args, against, log)
    if against not in levels:
        levels.insert(0, against)
    print("warming up the kernels ...", file=log, flush=True)
    warm_kernels()
    turns: dict = {}
    eps: dict = {}
    vec: dict = {}
    for name in levels:
        turns[name], eps[name], vec[name] = measure_level(args, name, against, log)
    rows = []
    for name in levels:
        row = level_row(name, load_fidelity(name).describe(), against, turns, eps, vec[name])
        rows.append(emit(args, row))
    if not args.json:
        print(format_table(rows))
        for r in rows:
            print(f"batched env, {r['level']}: {r['vec_note']}", file=log)
    if args.plot and not args.quick:
        pareto_plot(rows, Path(args.plot))
        print(f"plot: {args.plot}", file=log)
    if args.write:
        info = machine_info()
        for r in rows:
            write_measured(load_fidelity(r["level"]).path, r, info)
        print("wrote [measured] into configs/fidelity/*.toml", file=log)
    return 0


def measure_level(args, name: str, against: str, log) -> tuple[dict, list, dict]:
    """(a), (b) and (c) of one level: its turn (stored for ``reference`` unless
    ``--rerun-reference``), its episodes (stored for ``against`` when the file holds them) and
    its batched rates {N: (rate, note)}; each timed run after an untimed one that loads (or
    compiles) the level's kernels."""
    episodes = 1 if args.quick else args.episodes
    steps = 3 if args.quick else args.steps
    brush = "tiny_env" if args.quick else None
    live = args.quick or args.rerun_reference
    print(f"  {name}: the paper's turn ...", file=log, flush=True)
    if name == "reference" and not live:
        turn = stored_reference_turn()
    else:
        if not args.quick:
            turn_run(name, quick=True)  # untimed warm-up
        turn = turn_run(name, args.quick)
    stored = None if (live or name != against) else load_reference_episodes(name, episodes, steps)
    print(
        f"  {name}: {episodes} random episodes" + (" (stored)" if stored else "") + " ...",
        file=log,
        flush=True,
    )
    if stored is None:
        if episodes > 0:
            episode_run(name, 0, 2, brush)  # untimed warm-up: the env's own kernels
        stored = [episode_run(name, s, steps, brush) for s in range(episodes)]
    vec = {}
    n_steps = sum(len(e["F"]) for e in stored)
    wall = sum(e["wall_s"] for e in stored)
    single = n_steps / wall if wall > 0 else math.nan
    for n in [] if args.quick else args.vec_sizes:
        slow = batched_too_slow(single, n, args.vec_seconds)
        if slow:
            vec[n] = (math.nan, slow)
            continue
        print(f"  {name}: batched env, N = {n} ...", file=log, flush=True)
        vec[n] = vector_steps_per_s(name, n, args.vec_seconds, args.vec_steps)
    return turn, stored, vec


def batched_too_slow(single_rate: float, n: int, seconds: float) -> str:
    """The reason (c) skips a batched measurement of ``n`` envs, or "" to measure it: the
    batched env loops over single-env cores, so a warm-up and one timed step of ``n`` envs take
    about ``2 n / single_rate`` seconds; more than ``seconds`` is too slow to measure."""
    if not math.isfinite(single_rate) or single_rate <= 0:
        return "n/a (no single-env rate from (b) to plan the batched run)"
    need = 2.0 * n / single_rate
    if need > seconds:
        return (
            f"n/a (too slow: a warm-up and one timed step of {n} envs take ~{need:.0f} s at "
            f"{single_rate:.0f} env steps/s single, over --vec-seconds {seconds:g}; the batched "
            "env is a loop over single-env cores)"
        )
    return ""


def level_row(name: str, settings: str, against: str, turns: dict, eps: dict, vec: dict) -> dict:
    """One level's row: (a) against ``against`` (``turn_metrics``), (b) and (c)."""
    tr = turns[name]
    row: dict = {"level": name, "settings": settings, "against": against}
    row.update(turn_metrics(tr, turns[against]))
    row["turn_wall_per_sim_s"] = tr["wall_s"] / tr["sim_s"] if tr["sim_s"] > 0 else math.nan
    row["turn_status"] = tr["status"]
    if name == against:
        rf, rt, dc = 0.0, 0.0, 0.0
    else:
        rf, rt, dc = fm.compare_episodes(eps[name], eps[against])
    n_steps = sum(len(e["F"]) for e in eps[name])
    wall = sum(e["wall_s"] for e in eps[name])
    row.update(
        random_rms_force_error=rf,
        random_tip_force_error=rt,
        random_coverage_diff_points=dc,
        env_steps_per_s=n_steps / wall if wall > 0 else math.nan,
        episodes=len(eps[name]),
        env_steps=n_steps,
        episode_ends=[e["end"] for e in eps[name]],
        episodes_stored=eps[name][0].get("stored", "") if eps[name] else "",
    )
    notes = []
    for n in VEC_SIZES:
        rate, note = vec.get(n, (math.nan, "not measured"))
        row[f"env_steps_per_s_vec{n}"] = rate
        notes.append(f"N={n}: {note}")
    row["vec_note"] = "; ".join(notes)
    return row


def _write_references(args, level: str, log) -> int:
    """``--write-reference turn|episodes|all``: store (a) and/or (b) of ``level`` (the
    ``--against`` level, default ``reference``), then stop."""
    warm_kernels()
    what = args.write_reference
    if what in ("turn", "all"):
        print(f"writing the {level} turn to {REFERENCE_TURN_FILE} ...", file=log, flush=True)
        t0 = time.perf_counter()
        ref = write_reference_turn(level)
        print(
            f"  done in {time.perf_counter() - t0:.0f} s (stepping {ref['wall_s']:.0f} s); "
            f"{len(ref['events'][0])} stick-slip events",
            file=log,
            flush=True,
        )
    if what in ("episodes", "all"):
        print(
            f"writing {args.episodes} {level} episodes of up to {args.steps} steps to "
            f"{REFERENCE_EPISODES_FILE} ...",
            file=log,
            flush=True,
        )
        t0 = time.perf_counter()
        write_reference_episodes(level, args.episodes, args.steps, log=log)
        print(f"  done in {time.perf_counter() - t0:.0f} s", file=log, flush=True)
    return 0


def _pct(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{100 * x:.1f} %"


def _signed_pct(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{100 * x:+.1f} %"


def _num(x: float, fmt: str = ".1f") -> str:
    return "n/a" if not math.isfinite(x) else format(x, fmt)


def _settings(r: dict) -> str:
    """The level's description without its name."""
    text = r["settings"]
    return text[len(r["level"]) :].lstrip(": ") if text.startswith(r["level"]) else text


def format_table(rows) -> str:
    """Two Markdown tables: (a) the paper's turn; (b) random episodes and (c) speed."""

    def events(r):
        if r["events_ref"] == 0:
            return "—"
        return (
            f"{_num(r['event_dt_median_ms'])} / {_num(r['event_dt_max_ms'])} "
            f"({r['events_unmatched']} of {r['events_ref']} unmatched)"
        )

    def side(r):
        def one(k):
            return "—" if r[k] < 0 else str(r[k])

        if r["bristles"] == 0:
            return "—"
        pair = f"{one('buckling_same_side')} / {one('lateral_force_same_side')}"
        return f"{pair} of {r['bristles']}"

    def phase(k):
        return lambda r: (
            f"{_num(r[f'turn_phase_mean_{k}_N'], '.2f')} ({_signed_pct(r[f'turn_phase_err_{k}'])})"
        )

    turn = markdown_table(
        rows,
        [
            ("level", lambda r: r["level"]),
            ("TCP force err", lambda r: _pct(r["turn_rms_force_error"])),
            ("outside ±10 ms of events", lambda r: _pct(r["turn_rms_error_outside_events"])),
            ("press: mean ‖F‖ [N] (err)", phase("press")),
            ("hold: mean ‖F‖ [N] (err)", phase("hold")),
            ("sliding: mean ‖F‖ [N] (err)", phase("sliding")),
            ("event Δt median / max [ms]", events),
            ("same side at hold: tip offset / tip force", side),
            ("tip force err", lambda r: _pct(r["turn_tip_force_error"])),
            ("wall / sim s [s/s]", lambda r: _num(r["turn_wall_per_sim_s"], ".2f")),
            ("status", lambda r: r["turn_status"]),
        ],
    )
    rand = markdown_table(
        rows,
        [
            ("level", lambda r: r["level"]),
            ("random: TCP force err", lambda r: _pct(r["random_rms_force_error"])),
            ("random: tip force err", lambda r: _pct(r["random_tip_force_error"])),
            ("coverage diff [points]", lambda r: _num(r["random_coverage_diff_points"], ".2f")),
            (
                "episodes (env steps)",
                lambda r: (
                    f"{r['episodes']} ({r['env_steps']})"
                    + (" stored" if r.get("episodes_stored") else "")
                ),
            ),
            ("env steps/s (1 env)", lambda r: _num(r["env_steps_per_s"])),
            ("N = 16", lambda r: _num(r["env_steps_per_s_vec16"], ".0f")),
            ("N = 64", lambda r: _num(r["env_steps_per_s_vec64"], ".0f")),
            ("settings", _settings),
        ],
    )
    return (
        "(a) the paper's turn\n\n" + turn + "\n\n(b) random-policy episodes, (c) speed\n\n" + rand
    )


def pareto_plot(rows, path: Path) -> None:
    """Four panels, one point per level and measure.  Against wall time per simulated second of
    the turn (log x): the turn's relative force errors [%]; its event-time error [ms]; the
    bristles off the reference's side at the hold [count].  Against env steps per second (log
    x; one env, and N = 64 batched where measured): the random episodes' force errors [%] and
    coverage difference [points]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    for r in rows:
        errs = [abs(r[f"turn_phase_err_{k}"]) for k in PHASE_NAMES]
        r["_phase_max"] = max((e for e in errs if math.isfinite(e)), default=math.nan)
        for key in ("buckling_same_side", "lateral_force_same_side"):
            r[f"_{key}_off"] = float(r["bristles"] - r[key]) if r[key] >= 0 else math.nan
    wall = "turn_wall_per_sim_s"
    against = rows[0]["against"]
    panels = [
        (
            wall,
            f"paper turn: error vs {against} [%]",
            [
                ("turn_rms_force_error", "o", "TCP force RMS", 100),
                (
                    "turn_rms_error_outside_events",
                    "D",
                    "TCP force RMS outside ±10 ms of events",
                    100,
                ),
                ("_phase_max", "^", "largest |phase-mean error| (press, hold, sliding)", 100),
                ("turn_tip_force_error", "v", "per-tip normal force RMS", 100),
            ],
        ),
        (
            wall,
            "paper turn: stick→slip event-time error |Δt| [ms]",
            [("event_dt_median_ms", "o", "median", 1), ("event_dt_max_ms", "^", "largest", 1)],
        ),
        (
            wall,
            "paper turn: bristles off the reference's side [count]",
            [
                ("_buckling_same_side_off", "o", "by the tip's lateral offset", 1),
                ("_lateral_force_same_side_off", "s", "by the lateral tip force", 1),
            ],
        ),
        (
            "env_steps_per_s",
            "random episodes: error [%] / coverage [points]",
            [
                ("random_rms_force_error", "o", "TCP force RMS [%]", 100),
                ("random_tip_force_error", "v", "per-tip normal force RMS [%]", 100),
                ("random_coverage_diff_points", "s", "coverage difference [points]", 1),
            ],
        ),
    ]
    xlabels = {
        wall: "wall time per simulated second of the turn [s/s] (one core)",
        "env_steps_per_s": "env steps per second (one env; open: N = 64 batched) [1/s]",
    }
    fig, axes = plt.subplots(2, 2, figsize=(12.0, 8.4))
    for ax, (xkey, ylabel, series) in zip(axes.flat, panels):
        for key, mark, label, scale in series:
            pts = [(r[xkey], scale * r[key], r["level"]) for r in rows]
            pts = [(x, y, lv) for x, y, lv in pts if math.isfinite(x) and math.isfinite(y)]
            sc = ax.scatter([p[0] for p in pts], [p[1] for p in pts], marker=mark, label=label)
            for x, y, lv in pts:
                ax.annotate(lv, (x, y), textcoords="offset points", xytext=(4, 3), fontsize=7)
            if xkey == "env_steps_per_s":  # the batched rate of the same level, hollow
                vec = [(r["env_steps_per_s_vec64"], scale * r[key]) for r in rows]
                vec = [(x, y) for x, y in vec if math.isfinite(x) and math.isfinite(y)]
                if vec:
                    ax.scatter(
                        [v[0] for v in vec],
                        [v[1] for v in vec],
                        marker=mark,
                        facecolors="none",
                        edgecolors=sc.get_facecolor(),
                    )
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())
        if xkey == "env_steps_per_s":  # errors from 0 to many times the reference's force
            ax.set_yscale("symlog", linthresh=10.0)
            ax.set_ylim(0.0, 2.0 * max(ax.get_ylim()[1], 10.0))
        if series[0][0] == "_buckling_same_side_off":
            ax.set_ylim(-1.0, max([r["bristles"] for r in rows] + [1]) + 1.0)
        ax.set_xlabel(xlabels[xkey])
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7)
    for r in rows:
        for k in [k for k in r if k.startswith("_")]:
            del r[k]
    fig.suptitle("brush_env fidelity levels against reference (brush-env bench fidelity)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: the [measured] keys ``--write`` stores, with their unit comments
MEASURED_KEYS = (
    ("turn_rms_force_error", "[-] paper turn, RMS |F - F_ref| / RMS |F_ref|"),
    ("turn_rms_error_outside_events", "[-] the same, outside +-10 ms of the stick-slip events"),
    ("turn_phase_mean_press_N", "[N] mean |F| over the press"),
    ("turn_phase_mean_hold_N", "[N] mean |F| over the hold"),
    ("turn_phase_mean_sliding_N", "[N] mean |F| over the circle"),
    ("turn_phase_err_press", "[-] (mean - mean_ref) / mean_ref"),
    ("turn_phase_err_hold", "[-]"),
    ("turn_phase_err_sliding", "[-]"),
    ("event_dt_median_ms", "[ms] median |dt| of the matched stick-slip events"),
    ("event_dt_max_ms", "[ms] largest |dt|"),
    ("events_ref", "[count] reference events"),
    ("events_unmatched", "[count] without an event of the bristle within 100 ms"),
    ("buckling_same_side", "[count] bristles on the reference's side at the end of the hold"),
    ("lateral_force_same_side", "[count] the same by the lateral tip force's sign"),
    ("turn_tip_force_error", "[-] per-tip normal force, pooled RMS"),
    ("turn_wall_per_sim_s", "[s/s] one core"),
    ("random_rms_force_error", "[-]"),
    ("random_tip_force_error", "[-]"),
    ("random_coverage_diff_points", "[points]"),
    ("env_steps_per_s", "[1/s] one env, one core"),
    ("env_steps_per_s_vec16", "[1/s] batched, N = 16 (nan: not measured)"),
    ("env_steps_per_s_vec64", "[1/s] batched, N = 64 (nan: not measured)"),
)


def write_measured(path: Path, row: dict, info: dict) -> None:
    """Replace the ``[measured]`` table of a level's TOML file with ``row``'s figures (the keys
    of MEASURED_KEYS that ``row`` has)."""
    from ..engine.fidelity import MEASURED_MARK

    text = path.read_text()
    head = text.split(MEASURED_MARK)[0].rstrip() + "\n\n"

    def num(x):
        if isinstance(x, int):
            return str(x)
        return "nan" if not math.isfinite(x) else f"{x:.4g}"

    lines = [MEASURED_MARK, "[measured]", f'against = "{row["against"]}"']
    lines += [f"{k} = {num(row[k])}   # {unit}" for k, unit in MEASURED_KEYS if k in row]
    lines += [
        f'commit = "{info.get("commit", "")}"',
        f'date = "{info.get("date", "")}"',
        f'cpu = "{info.get("cpu", "")}"',
    ]
    path.write_text(head + "\n".join(lines) + "\n")


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per level on stdout (machine info on stderr)")
    add_flag(p, "--quick", "balanced against fast, a 0.16 s press, one 3-step episode (tests)")
    add_flag(p, "--write", "store each level's figures in its configs/fidelity file")
    p.add_argument("--episodes", type=int, default=20, help="random-policy episodes per level")
    p.add_argument("--steps", type=int, default=100, help="env steps per episode (at most)")
    p.add_argument("--levels", nargs="+", default=None, help="levels (default: all four)")
    p.add_argument("--against", default=None, help="the level the others are measured against")
    p.add_argument("--plot", default=str(PLOT), help="Pareto plot path ('' for none)")
    p.add_argument(
        "--vec-sizes",
        type=int,
        nargs="*",
        default=list(VEC_SIZES),
        help="batched env sizes N (gym.make_vec, vector_entry_point); none: skip",
    )
    p.add_argument(
        "--vec-seconds", type=float, default=10.0, help="wall [s] per batched measurement"
    )
    p.add_argument("--vec-steps", type=int, default=200, help="at most this many batched steps")
    p.add_argument(
        "--write-reference",
        choices=("turn", "episodes", "all"),
        default=None,
        help="compute and store the --against level's (default reference) turn with its tips "
        f"({REFERENCE_TURN_FILE.name}) and/or its --episodes x --steps random episodes "
        f"({REFERENCE_EPISODES_FILE.name}) in tests/data, then stop",
    )
    add_flag(
        p,
        "--rerun-reference",
        "run the reference level's turn and episodes instead of reading the stored ones",
    )
