"""Frames of the tooth row (ToothRow-v0's ``render``, the tooth-row experiment and docs figures).

Left: a 3-D view of the crowns, each triangle above the CEJ coloured by whether its coverage
sample is cleaned (green) or not (grey), the bristles as poly-lines (red where the tip carries
load, blue where free).  Right: the buccal surfaces seen from the brush (x along the row, y up
the crowns), and the cleaned share of every region.  ``tooth_row_figure(..., legend=True)`` adds
a legend for every colour and marker (the experiment's coverage.png).
"""

from __future__ import annotations

import numpy as np

from brush_env.geometry.teeth import surface_samples

CLEAN = (0.25, 0.70, 0.35)
DIRTY = (0.82, 0.82, 0.80)
ROOT = (0.93, 0.88, 0.80)
LOADED = "tab:red"  # a bristle whose tip carries load, and that tip
FREE = "tab:blue"  # a bristle whose tip is free


#: the two panels' places in the figure (left, bottom, width, height; figure fractions): apart
#: far enough that the 3-D view's z label and the map's y label never meet (issue 31)
PANEL_3D = (0.0, 0.06, 0.50, 0.90)
PANEL_MAP = (0.59, 0.30, 0.39, 0.50)
#: with a legend below, the panels move up by this much of the figure's height
LEGEND_ROOM = 0.16


def tooth_row_figure(
    teeth, coverage, chains, tip_force, height: int = 256, title: str = "", legend: bool = False
):
    """The matplotlib Figure of :func:`render_tooth_row` (2 height x height pixels at 100 dpi);
    ``legend``: a legend below the panels for every colour and marker (coverage.png)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    dpi = 100
    fig = plt.figure(figsize=(2 * height / dpi, height / dpi), dpi=dpi)
    # text in proportion to the frame (sizes in points are fixed, frames are not): the labels
    # keep their places at 256 px as at 480
    k = min(1.0, height / 480.0)
    big, small, tick = max(5.0, 10 * k), max(4.5, 7 * k), max(4.0, 6 * k)
    lift = LEGEND_ROOM if legend else 0.0
    l3, b3, w3, h3 = PANEL_3D
    ax = fig.add_axes((l3, b3 + lift, w3, h3 - lift), projection="3d")
    k0 = 0
    for s in teeth:
        V, T = s.vertices, s.triangles
        P = V[T]
        crown = P.mean(axis=1)[:, 1] >= 0.0
        n = int(crown.sum())
        cleaned = coverage.cleaned[k0 : k0 + n]
        k0 += n
        col = np.tile(np.asarray(ROOT), (len(T), 1))
        col[crown] = np.where(cleaned[:, None], CLEAN, DIRTY)
        ax.add_collection3d(Poly3DCollection(P, facecolors=col, edgecolors="none"))
    f = np.asarray(tip_force)
    for c, fi in zip(chains, f):
        ax.plot(c[:, 0], c[:, 1], c[:, 2], color=LOADED if fi > 0 else FREE, lw=0.6)
    lo, hi = coverage.extent
    box = ((lo[0] - 2, hi[0] + 2), (lo[1] - 4, hi[1] + 2), (-12.0, 12.0))
    ax.set_xlim(*box[0])
    ax.set_ylim(*box[1])
    ax.set_zlim(*box[2])
    ax.set_box_aspect([b[1] - b[0] for b in box])  # equal scales: the bristles' real length
    ax.view_init(elev=20, azim=-75)
    for axis, name in ((ax.xaxis, "x"), (ax.yaxis, "y"), (ax.zaxis, "z")):
        axis.set_label_text(f"{name} [mm]", fontsize=big)
        axis.labelpad = 2 + 6 * k
    ax.tick_params(labelsize=tick, pad=k)
    lm, bm, wm, hm = PANEL_MAP
    ax2 = fig.add_axes((lm, bm + 0.6 * lift, wm, hm - 0.6 * lift))
    pts = coverage.points
    vis = coverage.region == 0  # the buccal surfaces, seen from the brush (+z)
    ax2.scatter(
        pts[vis, 0],
        pts[vis, 1],
        s=1.5,
        c=np.where(coverage.cleaned[vis, None], CLEAN, DIRTY),
        marker="s",
        linewidths=0,
    )
    tips = chains[:, -1]
    ax2.scatter(tips[f > 0, 0], tips[f > 0, 1], s=6, c=LOADED)
    ax2.set_aspect("equal")
    ax2.set_xlabel("x [mm] (along the row)", fontsize=small)
    ax2.set_ylabel("y [mm] (CEJ = 0)", fontsize=small)
    ax2.tick_params(labelsize=tick)
    reg = coverage.by_region()
    ax2.set_title(
        title + "\nbuccal view; " + ", ".join(f"{r} {100 * v:.0f} %" for r, v in reg.items()),
        fontsize=small,
    )
    if legend:
        fig.legend(
            handles=legend_handles(), loc="lower center", ncol=3, fontsize=small, frameon=False
        )
    return fig


def legend_handles() -> list:
    """One entry per colour and marker of the figure."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    return [
        Patch(color=CLEAN, label="crown surface cleaned (a tip swept it within the force window)"),
        Patch(color=DIRTY, label="crown surface not cleaned yet"),
        Patch(color=ROOT, label="root surface below the CEJ (not scored)"),
        Line2D([], [], color=LOADED, lw=1.2, label="bristle whose tip carries load (3-D view)"),
        Line2D([], [], color=FREE, lw=1.2, label="bristle with a free tip (3-D view)"),
        Line2D([], [], ls="", marker="o", ms=4, color=LOADED, label="loaded tip (buccal view)"),
    ]


def render_tooth_row(
    teeth, coverage, chains, tip_force, height: int = 256, title: str = "", legend: bool = False
):
    """RGB frame (height, 2 height, 3) uint8 of the crowns, coverage and bristles."""
    import matplotlib.pyplot as plt

    fig = tooth_row_figure(teeth, coverage, chains, tip_force, height, title, legend)
    fig.canvas.draw()
    img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return img


def crown_triangles(teeth):
    """(triangles (n, 3, 3), region (n,)) of the crowns above the CEJ, in coverage-sample order."""
    tris, regs = [], []
    for s in teeth:
        P = s.vertices[s.triangles]
        crown = P.mean(axis=1)[:, 1] >= 0.0
        _, _, r = surface_samples(s.vertices, s.triangles)
        tris.append(P[crown])
        regs.append(r)
    return np.concatenate(tris), np.concatenate(regs)
