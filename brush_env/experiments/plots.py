"""Figures of a reference run (matplotlib, Agg): forces against the rotation angle (the paper's
Figure 7, and Figure 10 with the pitch error) and the deformed bristles at the jamming points
(Figure 9)."""

from __future__ import annotations

import math

import numpy as np

from .analysis import PAPER_JAMMING_ANGLES, TWO_PI, pi_label

#: PNG at zlib level 1 (PIL's default 6): the reference's two figures encode in 0.12 s instead of
#: 0.18 s, their files ~10 % larger (issue 32, session 38)
PNG_FAST = {"compress_level": 1}
#: Figure 7's margins (fractions of the figure; the legend below the axes, the title above):
#: what ``tight_layout(rect=(0, 0.06, 1, 1))`` found on the default run, left a little wider
_FORCES_LAYOUT = dict(left=0.085, right=0.98, bottom=0.12, top=0.915, hspace=0.14)
#: Figure 9's margins in inches (one or two events, each a side and a top view row; four
#: columns): what ``tight_layout(rect=(0, 0.06, 1, 0.95), h_pad=3.0)`` found on the default run
#: (two events, 14.4 x 10 in): the title above, the legend below, a title and an x label between
#: two rows
_SHAPES_IN = dict(top=1.36, bottom=1.13, gap=0.99, left=0.65, right=0.49, wspace=0.24)


def _shapes_layout(fig, rows: int) -> None:
    """Figure 9's fixed margins (``_SHAPES_IN``) for ``rows`` rows of axes on ``fig``."""
    w, h = fig.get_size_inches()
    m = _SHAPES_IN
    mean_ax = (h - m["top"] - m["bottom"] - (rows - 1) * m["gap"]) / rows
    fig.subplots_adjust(
        left=m["left"] / w,
        right=1.0 - m["right"] / w,
        bottom=m["bottom"] / h,
        top=1.0 - m["top"] / h,
        wspace=m["wspace"],
        hspace=m["gap"] / mean_ax,
    )


def _pi_ticks(ax, lo, hi, denom=4):
    step = math.pi / denom
    k0, k1 = int(math.ceil(lo / step - 1e-9)), int(math.floor(hi / step + 1e-9))
    ks = list(range(k0, k1 + 1))
    stride = max(1, len(ks) // 14 + 1)
    ks = ks[::stride]
    ax.set_xticks([k * step for k in ks])
    ax.set_xticklabels([pi_label(k * step, denom) for k in ks])


def _plot_range(theta_end):
    if theta_end > TWO_PI + 0.25:
        k = int(math.ceil(theta_end / TWO_PI - 1e-9))
        full = abs(theta_end - k * TWO_PI) < 1e-6
        return (
            TWO_PI,
            theta_end,
            (f"turns 2-{k}" if full and k > 2 else f"θ in [2π, {theta_end / math.pi:.2f}π]"),
        )
    if theta_end > 0.5 * math.pi:
        return 0.5 * math.pi, theta_end, "θ ≥ π/2 (turn 1 after the excluded quarter)"
    return 0.0, max(theta_end, 1e-3), "whole run (θ < π/2: no analysis range)"


def plot_forces_vs_angle(
    path, recs, theta, analysis, pitch_series, pitch_window, title="", complete=False
):
    """Figure 7 (with a pitch run, Figure 10): Fx, Fy, Fz and |F_h| against θ over turns 2-4.

    ``complete``: the run reached the end of the motion, whose last quarter turn (the final
    MoveL segment) is shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    base = recs["baseline"]
    th_end = float(theta[base.n - 1])
    lo, hi, what = _plot_range(th_end)
    fig, axes = plt.subplots(
        4, 1, figsize=(11, 10), sharex=True, gridspec_kw=dict(height_ratios=[3, 3, 3, 2])
    )
    styles = {
        "baseline": dict(color="C0", lw=1.2, label="without pitch error"),
        "pitch": dict(color="C3", lw=1.2, ls="--", label="with pitch error (eq 12)"),
    }
    for name, r in recs.items():
        st = dict(styles[name])
        if len(recs) == 1:
            st["label"] = None
        _plot_run(axes, r, theta, (lo, hi), st, (analysis.get(name) or {}).get("jamming"))
    if complete:
        _final_move(axes, theta[base.n - 1], lo, hi)
    _paper_angles(axes, lo, hi)
    if "pitch" in recs:
        _pitch_overlay(axes, theta, (lo, hi), pitch_series["pitch"], pitch_window)
    _label_axes(axes, ["Fx [N]", "Fy [N]", "Fz [N]", "|F_h| [N]"], lo, hi)
    fig.legend(
        handles=_legend_handles(plt, recs, styles, complete),
        loc="lower center",
        ncol=2,
        fontsize=8,
        frameon=False,
    )
    title = f"{title}\n{_offset_note(analysis.get('baseline'))}"
    if "pitch" in recs:
        fig.suptitle(
            f"Forces vs rotation angle, {what}: with and without the pitch error "
            f"(paper Figure 10)\n{title}",
            fontsize=10,
        )
    else:
        fig.suptitle(f"Forces vs rotation angle, {what} (paper Figure 7)\n{title}", fontsize=10)
    # fixed margins (what tight_layout found for this layout, with room for wider tick labels):
    # tight_layout measures every text of the figure in an extra draw, ~35 % of its time
    fig.subplots_adjust(**_FORCES_LAYOUT)
    fig.savefig(path, dpi=110, pil_kwargs=PNG_FAST)
    plt.close(fig)


def _plot_run(axes, r, theta, span, st, jam) -> None:
    """One run's Fx, Fy, Fz, |F_h| over θ in ``span`` in style ``st``, with its detected jamming
    peaks (``jam``: its jamming analysis, or None) marked."""
    lo, hi = span
    n = r.n
    th = theta[:n]
    m = (th >= lo) & (th <= hi)
    F = r.step["F"][:n]
    ys = [F[:, 0], F[:, 1], F[:, 2], np.hypot(F[:, 0], F[:, 1])]
    for ax, y in zip(axes, ys):
        ax.plot(th[m], y[m], **st)
    if not jam:
        return
    for p in jam["peaks"]:
        if lo <= p["theta_rad"] <= hi:
            i = int(np.argmin(np.abs(th - p["theta_rad"])))
            for ax, y in zip(axes, ys):
                ax.axvline(p["theta_rad"], color=st["color"], lw=0.6, ls=":", alpha=0.8)
                ax.plot(th[i], y[i], "v", color=st["color"], ms=6, mec="k", mew=0.5)


def _paper_angles(axes, lo, hi) -> None:
    """The paper's jamming angles 9π/4 + 2πk and 13π/4 + 2πk in [lo, hi]."""
    for a0 in PAPER_JAMMING_ANGLES:
        k = math.floor((lo - a0) / TWO_PI)
        a = a0 + k * TWO_PI
        while a <= hi:
            if a >= lo:
                for ax in axes:
                    ax.axvline(a, color="0.6", lw=1.0, ls="-.", alpha=0.6, zorder=0)
            a += TWO_PI


def _pitch_overlay(axes, theta, span, pitch, pitch_window) -> None:
    """The perturbed window shaded and the imposed eq-12 ``pitch`` [rad] on a second axis of the
    last panel."""
    lo, hi = span
    for ax in axes:
        ax.axvspan(pitch_window[0], pitch_window[1], color="C3", alpha=0.08, zorder=0)
    ax2 = axes[3].twinx()
    m = (theta >= lo) & (theta <= hi)
    ax2.plot(theta[m], np.degrees(pitch[m]), color="C3", lw=0.8, alpha=0.6)
    ax2.set_ylabel("pitch [deg]", color="C3")


def _label_axes(axes, names, lo, hi) -> None:
    """Y labels and grids, the θ axis in multiples of π/4 over [lo, hi]."""
    for ax, nm in zip(axes, names):
        ax.set_ylabel(nm)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("rotation angle θ [rad] (0 at the start point P0)")
    _pi_ticks(axes[-1], lo, hi, 4)
    axes[0].set_xlim(lo, hi)


def _final_move(axes, theta_end, lo, hi) -> None:
    """Shade the last quarter turn: the final MoveL segment runs straight into the last control
    point (no blend) and stops there, so its forces are not those of the circle -- the same reason
    the paper excludes the first quarter (P0 -> P1)."""
    a = max(lo, float(theta_end) - 0.5 * math.pi)
    if theta_end > TWO_PI and a < hi:
        for ax in axes:
            ax.axvspan(a, hi, color="0.85", alpha=0.5, zorder=0, lw=0)


def _legend_handles(plt, recs, styles, complete) -> list:
    """Legend entries: the runs, the detected peaks, the paper's angles, the final move."""
    from matplotlib.patches import Patch

    handles = [plt.Line2D([], [], **{k: v for k, v in styles[n].items()}) for n in recs]
    if len(recs) == 1:
        handles[0].set_label("F: force the robot applies to the brush (robot base frame, z up)")
    handles += [
        plt.Line2D(
            [],
            [],
            ls=":",
            marker="v",
            color="C0",
            mec="k",
            mew=0.5,
            label="detected jamming peak of |F_h| (our run)",
        ),
        plt.Line2D([], [], ls="-.", color="0.6", label="paper's jamming angles 9π/4, 13π/4 + 2πk"),
    ]
    if complete:
        handles.append(
            Patch(
                color="0.85",
                alpha=0.5,
                label="final move into the last MoveL point (not the circle)",
            )
        )
    return handles


def _offset_note(analysis) -> str:
    """One line: where our peaks sit against the paper's angles (mod 2π)."""
    jam = (analysis or {}).get("jamming") or {}
    parts = []
    for name, ev in (jam.get("events") or {}).items():
        if ev.get("count"):
            paper = math.degrees(ev["paper_angle_mod_2pi_rad"])
            ours = ev["mean_angle_mod_2pi_deg"]
            d = (ours - paper + 180.0) % 360.0 - 180.0
            parts.append(f"near {name}: ours {ours:.0f}° vs paper {paper:.0f}° ({d:+.0f}°)")
    if not parts:
        return "no jamming peak detected"
    return "jamming peaks mod 2π, " + "; ".join(parts)


def mean_angle_text(ev: dict) -> str:
    """The jamming event's mean angle as the run prints it (``brush-env reference``) and the
    figures quote it, so that both read the same figure: ``54.0° mod 360°``."""
    return f"{ev['mean_angle_mod_2pi_deg']:.1f}° mod 360°"


def _shape_events(analysis, theta_lo, theta_hi):
    """The angles to show in deformed_shapes.png: the jamming peaks of the first turn that has
    them (>= 2 if possible), else the paper's angles in range, else two evenly spaced angles.
    A peak's label gives its own angle and the mean over every turn's peak of that event (the
    figure the run prints)."""
    jam = analysis.get("jamming") if analysis else None
    peaks = jam["peaks"] if jam else []
    if peaks:
        events = jam.get("events") or {}
        turns = sorted({p["turn"] for p in peaks})
        t = next((k for k in turns if k >= 2), turns[0])
        out = []
        for p in [p for p in peaks if p["turn"] == t][:2]:
            name = p["nearest_paper_angle"]
            ev = events.get(name) or {}
            mean = (
                f"; mean of {ev['count']} turn(s): {mean_angle_text(ev)}" if ev.get("count") else ""
            )
            out.append(
                (
                    p["theta_rad"],
                    f"paper's {name} jamming: our turn-{t} peak at θ = {p['theta_label']} "
                    f"({p['theta_mod_2pi_deg']:.1f}° mod 360°){mean}",
                )
            )
        return out
    out = []
    for a0 in PAPER_JAMMING_ANGLES:
        for a in (a0 - TWO_PI, a0, a0 + TWO_PI):
            if theta_lo <= a <= theta_hi:
                out.append((a, f"paper's jamming angle {pi_label(a)} (no peak detected)"))
                break
    if out:
        return out[:2]
    return [
        (theta_lo + f * (theta_hi - theta_lo), "no jamming peak detected") for f in (0.35, 0.85)
    ]


def plot_deformed_shapes(
    path,
    rec,
    theta,
    pose,
    sim,
    brush_cfg,
    analysis,
    times,
    offsets=(-math.pi / 8, -math.pi / 24, 0.0, math.pi / 8),
):
    """Figure 9: bristle centre lines around each jamming point, side (x-z) and top (x-y) views.

    Coordinates are world (robot base) axes relative to the TCP position; the plate is z = 0 in the
    side view.  Columns: angles θ_peak + offsets; rows: side and top view of each event.  Tips in
    contact are drawn red, the others black; the arrow in the top view is the TCP velocity.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = rec.shapes["row"][: rec.ns]
    th_end = float(theta[rec.n - 1])
    lo = 0.5 * math.pi if th_end > 0.5 * math.pi else 0.0
    events = _shape_events(analysis, lo, th_end)
    m = sim.model
    groups = [b.group for b in brush_cfg.bristles]
    gnames = sorted(set(groups))
    gcol = {g: f"C{k}" for k, g in enumerate(gnames)}
    ncol = len(offsets)
    fig, axes = plt.subplots(
        2 * len(events),
        ncol,
        figsize=(3.6 * ncol, 4.6 * len(events) + 0.8),
        squeeze=False,
        gridspec_kw=dict(height_ratios=[1.6, 2.4] * len(events)),
    )
    L = brush_cfg.max_length
    span = (np.ptp(m.root_p[:, 0]) / 2 + 0.7 * L, np.ptp(m.root_p[:, 1]) / 2 + 0.7 * L)
    colours = [gcol[g] for g in groups]
    th_s = theta[rows]
    picks = [[int(np.argmin(np.abs(th_s - (th0 + off)))) for off in offsets] for th0, _ in events]
    # one arrow scale for every panel: the fastest TCP speed shown is half the view's height
    vmax = max((_tcp_speed(pose[0], times, int(rows[k])) for ks in picks for k in ks), default=0)
    arrow = ArrowScale(0.5 * span[1], vmax)
    for e, ks in enumerate(picks):
        for c, (k, off) in enumerate(zip(ks, offsets)):
            ax_s, ax_t = axes[2 * e, c], axes[2 * e + 1, c]
            _draw_shapes(ax_s, ax_t, rec, k, pose, m, colours, span, times, arrow)
            _title_panel(ax_s, ax_t, th_s[k], off, first_column=c == 0)
    handles = [plt.Line2D([], [], color=gcol[g], label=f"bristles: {g}") for g in gnames]
    handles += [
        plt.Line2D([], [], ls="", marker="o", color="r", ms=5, label="tip in contact"),
        plt.Line2D([], [], ls="", marker="o", color="k", ms=5, label="tip not in contact"),
        plt.Line2D([], [], ls="", marker="s", color="0.5", ms=5, label="bristle root (top view)"),
        plt.Line2D([], [], color="C3", lw=1.5, label=arrow.legend()),
    ]
    fig.legend(handles=handles, loc="lower center", fontsize=9, ncol=3, frameon=False)
    fig.suptitle(
        f"Deformed bristles around the two jamming points of a turn (paper Figure 9), brush "
        f"'{brush_cfg.name}'\nworld (robot base) axes relative to the TCP; plate at z = 0; "
        "columns: θ before, at and after the peak",
        fontsize=11,
    )
    _shapes_layout(fig, 2 * len(events))  # fixed, as Figure 7's (``_FORCES_LAYOUT``)
    h_in = fig.get_size_inches()[1]  # row labels 0.27 in above the row's axes, over its titles
    for e, (_, label) in enumerate(events):  # row labels placed after the layout is fixed
        pos = axes[2 * e, 0].get_position()
        fig.text(pos.x0, pos.y1 + 0.27 / h_in, label, fontsize=10, fontweight="bold", ha="left")
    fig.savefig(path, dpi=100, pil_kwargs=PNG_FAST)
    plt.close(fig)


class ArrowScale:
    """Velocity arrows drawn to one scale: ``length`` [mm of the view] for ``vmax`` [mm/s]."""

    def __init__(self, length: float, vmax: float) -> None:
        self.length, self.vmax = float(length), float(vmax)

    def mm(self, v: float) -> float:
        return self.length * v / self.vmax if self.vmax > 0 else 0.0

    def legend(self) -> str:
        if self.vmax <= 0:
            return "TCP velocity (top view; the TCP is at rest here)"
        return (
            f"TCP velocity (top view): {self.length:.1f} mm of arrow = {self.vmax:.0f} mm/s; "
            "the speed is printed at each arrow"
        )


def _tcp_speed(P, times, i: int) -> float:
    """Horizontal TCP speed [mm/s] at row ``i`` (central difference of the positions)."""
    a, b = max(i - 1, 0), min(i + 1, len(P) - 1)
    dt = float(times[b] - times[a]) if b < len(times) else 0.0
    return float(np.linalg.norm((P[b] - P[a])[:2]) / dt) if dt > 0 else 0.0


def _draw_shapes(ax_s, ax_t, rec, k, pose, m, colours, span, times, arrow) -> None:
    """Stored shape ``k`` of ``rec``: every bristle's centre line (root, bodies, tip) in the side
    (``ax_s``) and top (``ax_t``) view relative to the TCP, the tips red where in contact, the
    plate line, the view limits (``span`` = half-widths in x, y [mm]) and the TCP velocity (to
    ``arrow``'s scale, its speed written beside it)."""
    P, R = pose
    i = int(rec.shapes["row"][k])
    p_tcp, R_tcp = P[i], R[i]
    body = rec.shapes["body"][k].astype(float)
    tips = rec.shapes["tip"][k].astype(float)
    cont = rec.shapes["contact"][k]
    from matplotlib.collections import LineCollection

    shift = np.array([p_tcp[0], p_tcp[1], 0.0])
    roots = p_tcp + m.root_p @ R_tcp.T - shift
    tips = tips - shift
    body = body - shift
    # one collection per view and one marker line per colour, not a Line2D per bristle and
    # view (~200 artists per panel): ~30 % of this figure's time; the rest is matplotlib's
    # tick and text layout of its 16 axes
    lines = [
        np.vstack([roots[j], body[m.bstart[j] : m.bstart[j + 1]], tips[j]])
        for j in range(m.n_bristles)
    ]
    for ax, c in ((ax_s, 2), (ax_t, 1)):
        segs = [ln[:, [0, c]] for ln in lines]
        ax.add_collection(LineCollection(segs, colors=colours, linewidths=1.0, alpha=0.8))
        for touching, tc in ((False, "k"), (True, "r")):
            sel = cont == touching
            ax.plot(tips[sel, 0], tips[sel, c], "o", ls="", color=tc, ms=2.5)
    for col in dict.fromkeys(colours):
        sel = np.array([cj == col for cj in colours])
        ax_t.plot(roots[sel, 0], roots[sel, 1], "s", ls="", color=col, ms=2.5)
    spanx, spany = span
    ax_s.axhline(0.0, color="0.3", lw=1.5)
    ax_s.set_xlim(-spanx, spanx)
    ax_s.set_ylim(min(-1.0, float(tips[:, 2].min()) - 0.5), p_tcp[2] + 1.0)
    ax_t.set_xlim(-spanx, spanx)
    ax_t.set_ylim(-spany, spany)
    if i + 1 < len(P):
        v = P[min(i + 1, len(P) - 1)] - P[max(i - 1, 0)]
        nv = np.linalg.norm(v[:2])
        speed = _tcp_speed(P, times, i)
        if nv > 0 and speed > 0:
            d = v[:2] / nv * arrow.mm(speed)
            ax_t.annotate(
                "",
                xy=(d[0], d[1]),
                xytext=(0, 0),
                arrowprops=dict(arrowstyle="->", color="C3", lw=1.5),
            )
            ax_t.annotate(
                f"{speed:.0f} mm/s",
                xy=(d[0], d[1]),
                xytext=(3, 3),
                textcoords="offset points",
                color="C3",
                fontsize=7,
            )


def _title_panel(ax_s, ax_t, th: float, off: float, first_column: bool) -> None:
    """Grid, ticks, the angle ``th`` [rad] as title ("[peak]" at offset 0) and axis labels."""
    # no fixed aspect: panels fill their cells (the side view stretches z, readable)
    for ax in (ax_s, ax_t):
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
        # at most ~4 intervals a panel (-5, 0, 5 mm): matplotlib builds and draws every tick's
        # lines and label, most of this figure's 16 axes' time (1.0 -> 0.75 s, issue 32)
        ax.locator_params(nbins=4)
    ax_s.set_title(
        f"θ = {th / math.pi:.3f}π ({math.degrees(th % TWO_PI):.0f}°)"
        f"{'  [peak]' if off == 0 else ''}",
        fontsize=9,
    )
    if first_column:
        ax_s.set_ylabel("side: z [mm]", fontsize=8)
        ax_t.set_ylabel("top: y - y_TCP [mm]", fontsize=8)
    ax_t.set_xlabel("x - x_TCP [mm]", fontsize=8)
