"""Simulating the planned motion and recording it: per-step wrench and contact sums, sampled tip
states and bristle centre lines (preallocated)."""

from __future__ import annotations

import math
import time

import numpy as np

from ..engine import SimulationDivergence
from ..engine.chain_rollout import make_follow_record
from ..engine.simulator import record_row


class _Recorder:
    """Preallocated per-step and sampled (tips, shapes) records of one run."""

    def __init__(self, n_rows, nb, nbody, tips_stride, shapes_stride):
        self.n = 0
        self.tips_stride, self.shapes_stride = tips_stride, shapes_stride
        self.step = dict(
            time=np.zeros(n_rows),
            F=np.zeros((n_rows, 3)),
            M=np.zeros((n_rows, 3)),
            Fn=np.zeros(n_rows),
            Ft=np.zeros(n_rows),
            Ft_abs=np.zeros(n_rows),
            n_contact=np.zeros(n_rows, np.int32),
            max_pen=np.zeros(n_rows),
            iters=np.zeros(n_rows, np.int32),
            subs=np.zeros(n_rows, np.int32),
        )
        nt = (n_rows - 1) // tips_stride + 1
        ns = (n_rows - 1) // shapes_stride + 1
        f32 = np.float32
        self.tips = dict(
            row=np.zeros(nt, np.int64),
            pos=np.zeros((nt, nb, 3), f32),
            vel=np.zeros((nt, nb, 3), f32),
            fn=np.zeros((nt, nb), f32),
            ft=np.zeros((nt, nb, 3), f32),
            fc=np.zeros((nt, nb, 3), f32),
            contact=np.zeros((nt, nb), bool),
            sliding=np.zeros((nt, nb), bool),
            pen=np.zeros((nt, nb), f32),
            tiptip=np.zeros((nt, nb), f32),
        )
        self.nt = 0
        self.shapes = dict(
            row=np.zeros(ns, np.int64),
            body=np.zeros((ns, nbody, 3), f32),
            tip=np.zeros((ns, nb, 3), f32),
            contact=np.zeros((ns, nb), bool),
        )
        self.ns = 0

    def copy(self):
        new = _Recorder.__new__(_Recorder)
        new.n, new.nt, new.ns = self.n, self.nt, self.ns
        new.tips_stride, new.shapes_stride = self.tips_stride, self.shapes_stride
        new.step = {k: v.copy() for k, v in self.step.items()}
        new.tips = {k: v.copy() for k, v in self.tips.items()}
        new.shapes = {k: v.copy() for k, v in self.shapes.items()}
        return new

    def add_rows(self, fr, n):
        """The next n rows from a ``Simulator.follow`` record fr (``chain_rollout.FollowRecord``),
        every row at once: the TCP wrench, the tips' force sums, contacts, deepest penetration and
        solver counts per row, the tips every tips_stride rows and the bristles' centre lines
        every shapes_stride rows (from ``fr.body``: the follow kept them, ``kept_rows``)."""
        i = self.n
        rows = slice(i, i + n)
        s = self.step
        fn, ft = fr.fn[:n], fr.ft[:n]
        s["time"][rows] = fr.t[:n]
        s["F"][rows] = fr.FM[:n, 0:3]
        s["M"][rows] = fr.FM[:n, 3:6]
        s["Fn"][rows] = fn.sum(axis=1)
        s["Ft"][rows] = np.linalg.norm(ft.sum(axis=1), axis=1)
        s["Ft_abs"][rows] = np.linalg.norm(ft, axis=2).sum(axis=1)
        s["n_contact"][rows] = np.count_nonzero(fn > 0.0, axis=1)
        s["max_pen"][rows] = fr.pen[:n].max(axis=1) if fn.shape[1] else 0.0
        s["iters"][rows] = fr.iters[:n]
        s["subs"][rows] = fr.nsub[:n]
        ks = np.flatnonzero((np.arange(i, i + n) % self.tips_stride) == 0)
        if ks.size:
            t = self.tips
            dst = slice(self.nt, self.nt + ks.size)
            pos = fr.tips[ks, :, 0:3]
            fnk, ftk = fr.fn[ks], fr.ft[ks]
            contact = fnk > 0.0
            d = pos - fr.cpt[ks]
            nd = np.linalg.norm(d, axis=2, keepdims=True)
            nrm = np.where(nd > 1e-12, d / np.maximum(nd, 1e-300), 0.0)
            t["row"][dst] = i + ks
            t["pos"][dst] = pos
            t["vel"][dst] = fr.tips[ks, :, 3:6]
            t["fn"][dst] = fnk
            t["ft"][dst] = ftk
            t["fc"][dst] = np.where(contact[..., None], fnk[..., None] * nrm + ftk, 0.0)
            t["contact"][dst] = contact
            t["sliding"][dst] = fr.slide[ks] != 0
            t["pen"][dst] = fr.pen[ks]
            t["tiptip"][dst] = fr.ftt[ks]
            self.nt += ks.size
        kept = self.kept_rows(i, n)
        if kept.size:
            if fr.body.shape[0] < kept.size:
                raise ValueError(f"rows {i + kept}: the follow kept no body centres for them")
            dst = slice(self.ns, self.ns + kept.size)
            sh = self.shapes
            sh["row"][dst] = i + kept
            sh["body"][dst] = fr.body[: kept.size]
            sh["tip"][dst] = fr.tips[kept, :, 0:3]
            sh["contact"][dst] = fr.fn[kept] > 0.0
            self.ns += kept.size
        self.n += n

    def kept_rows(self, i, n):
        """Which of the n rows from row i have their bristle centre lines kept (offsets)."""
        return np.flatnonzero((np.arange(i, i + n) % self.shapes_stride) == 0)


#: engine steps per ``Simulator.follow`` call of the reference (the progress bar moves on
#: between calls): each call costs ~0.4 ms of Python around the compiled steps; when a call
#: ended at every kept centre line (20 steps) that was 2 % of the 4-turn run's simulation
#: (issue 32, session 37)
CHUNK = 1000


def _simulate(sim, P, R, rec, theta, i0, i1, bar, label):
    """Step rows i0..i1-1 (row i is the pose at time i·dt; row 0 is the reset), in
    ``Simulator.follow`` calls of up to CHUNK steps (the steps compiled, no Python between
    them), which keep the body centres of the rows whose bristle centre lines are stored."""
    i = i0
    while i < i1:
        j = min(i1, i + CHUNK)
        run = sim.follow(P[i:j], R[i:j], keep_bodies=rec.kept_rows(i, j - i))
        rec.add_rows(run.record, run.done)
        if bar is not None:
            bar.update(run.done)
            k = i + run.done - 1
            if run.done:
                bar.set_postfix_str(
                    f"{label} θ={theta[k] / math.pi:5.2f}π Fz={rec.step['F'][k, 2]:+.2f} N",
                    refresh=False,
                )
        if run.error is not None:
            raise run.error
        i = j


def _shared_prefix(poses, n_steps) -> int:
    """First row whose pose differs between the baseline and the pitched run (n_steps + 1 when
    the perturbation does not start within the run)."""
    if "pitch" not in poses:
        return n_steps + 1
    (P, R), (Pp, Rp) = poses["baseline"], poses["pitch"]
    diff = np.flatnonzero((np.abs(Pp - P).max(axis=1) > 0) | (np.abs(Rp - R).max(axis=(1, 2)) > 0))
    return int(diff[0]) if diff.size else n_steps + 1


def simulate_runs(plan, progress: bool):
    """Step the simulator along the baseline motion and, with a pitch error, along the pitched
    one, which shares the baseline's prefix up to the perturbation (its state is restored there).
    Returns ``(recorders, status, perf)`` by run name; a divergence ends that run and is reported
    in its status."""
    from tqdm.auto import tqdm

    sim, theta, n_steps = plan.sim, plan.theta, plan.n_steps
    P, R = plan.poses["baseline"]
    rec = _Recorder(
        n_steps + 1, sim.model.n_bristles, sim.model.n_bodies, plan.tips_stride, plan.shapes_stride
    )
    # the reset, as a follow's row (its centre lines kept)
    row0 = make_follow_record(1, sim.model.n_bristles, 1, sim.model.n_bodies)
    record_row(row0, 0, sim.reset(P[0], R[0]))
    row0.body[0] = sim.state.pos
    rec.add_rows(row0, 1)
    branch = _shared_prefix(plan.poses, n_steps)
    total = n_steps + (n_steps + 1 - branch if "pitch" in plan.poses else 0)
    bar = (
        tqdm(total=total, unit="step", desc="reference", mininterval=0.5, dynamic_ncols=True)
        if progress
        else None
    )
    status, recs, perf = {}, {}, {}
    snapshot = rec_snapshot = None
    t0 = time.perf_counter()
    try:
        if branch <= n_steps:
            _simulate(sim, P, R, rec, theta, 1, branch, bar, "baseline")
            snapshot, rec_snapshot = sim.get_state(), rec.copy()
            _simulate(sim, P, R, rec, theta, branch, n_steps + 1, bar, "baseline")
        else:
            _simulate(sim, P, R, rec, theta, 1, n_steps + 1, bar, "baseline")
        status["baseline"] = "ok"
    except SimulationDivergence as exc:
        status["baseline"] = f"diverged: {exc}"
    recs["baseline"] = rec
    perf["baseline"] = dict(
        wall_s=time.perf_counter() - t0,
        steps=rec.n - 1,
        simulated_s=float(rec.step["time"][rec.n - 1]),
    )
    if "pitch" in plan.poses:
        recs["pitch"], status["pitch"], perf["pitch"] = _pitch_run(
            plan, rec, status["baseline"], branch, snapshot, rec_snapshot, bar
        )
    if bar is not None:
        bar.close()
    return recs, status, perf


def _pitch_run(plan, rec, baseline_status, branch, snapshot, rec_snapshot, bar):
    """The pitched run from the shared prefix's state: (recorder, status, perf)."""
    sim, n_steps = plan.sim, plan.n_steps
    not_run = dict(wall_s=0.0, steps=0, shared_prefix_steps=rec.n - 1, simulated_s=0.0)
    if branch > n_steps:  # the perturbation does not start within the run: same as baseline
        return rec.copy(), baseline_status, not_run
    if snapshot is None:  # the baseline diverged before the perturbation starts
        return (
            rec.copy(),
            "not run: the baseline diverged before the perturbation starts",
            not_run,
        )
    Pp, Rp = plan.poses["pitch"]
    t0 = time.perf_counter()
    sim.set_state(snapshot)
    rec_p = rec_snapshot
    try:
        _simulate(sim, Pp, Rp, rec_p, plan.theta, branch, n_steps + 1, bar, "pitch")
        status = "ok"
    except SimulationDivergence as exc:
        status = f"diverged: {exc}"
    perf = dict(
        wall_s=time.perf_counter() - t0,
        steps=rec_p.n - branch,
        shared_prefix_steps=branch - 1,
        simulated_s=float(rec_p.step["time"][rec_p.n - 1] - plan.times[branch - 1]),
    )
    return rec_p, status, perf
