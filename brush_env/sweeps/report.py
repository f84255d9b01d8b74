"""``brush-env sweep-report DIR``: the effects of each varied parameter and a sensitivity ranking,
written to ``DIR/report.md`` with figures (issue 16).

* One figure per varied parameter (``effect_<param>.png``): every metric against it, one dot per
  run (the motions in colours).
* Sensitivity: standardised regression coefficients (SRC): the metric and the parameters are
  scaled to zero mean and unit standard deviation, then fitted linearly by least squares.
  |SRC| ranks how much one standard deviation of a parameter moves the metric, and R^2 says how
  much of the metric a linear model explains (SRC is trustworthy where R^2 >~ 0.7; Saltelli et
  al., *Global Sensitivity Analysis: The Primer*, 2008, ch. 1).  SRC needs no special design:
  it works on grid, LHS and Sobol samples alike.
* A sentence per peak-force metric names the parameter that moves it most.
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np

from .spec import METRICS, key_unit
from .sweep import read_table


def src(X: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    """Standardised regression coefficients of y on the columns of X, and R^2."""
    Xs = (X - X.mean(axis=0)) / np.where(X.std(axis=0) > 0, X.std(axis=0), 1.0)
    sy = y.std()
    if sy == 0:
        return np.zeros(X.shape[1]), 0.0
    ys = (y - y.mean()) / sy
    A = np.column_stack([Xs, np.ones(len(ys))])
    coef, *_ = np.linalg.lstsq(A, ys, rcond=None)
    resid = ys - A @ coef
    return coef[:-1], float(1.0 - resid @ resid / (ys @ ys))


#: words for the last part of a varied key (its unit suffix removed)
_PARAM_WORDS = {
    "E": "Young's modulus E",
    "width": "section width",
    "thickness": "section thickness",
    "length": "bristle length",
    "tip_radius": "tip sphere radius",
    "density": "density",
    "speed": "tool speed",
    "accel": "tool acceleration",
    "press_depth": "press depth",
    "turns": "turns",
}
_UNIT_SUFFIXES = ("_mm", "_MPa", "_deg", "_s", "_N", "_t_mm3", "_kg_m3")


def param_words(key: str) -> str:
    """A varied key in words with its unit: ``brush.sections.*.width_mm`` -> ``section width
    (every entry of brush.sections) [mm]``."""
    parts = key.split(".")
    last = parts[-1]
    for suffix in _UNIT_SUFFIXES:
        if last.endswith(suffix):
            last = last[: -len(suffix)]
            break
    words = _PARAM_WORDS.get(last, last.replace("_", " "))
    if "*" in parts:
        words += f" (every entry of {'.'.join(parts[: parts.index('*')])})"
    return f"{words} [{key_unit(key)}]"


def metric_words(metric: str) -> str:
    """A metric's description in words with its unit, wrapped for a panel title."""
    unit, what = METRICS[metric]
    return textwrap.fill(f"{what} [{unit}]", 42)


def _fit_line(ax, x, y, color, slope_unit: str) -> None:
    """The least-squares line through the dots (dashed) and its slope in the legend; none
    with fewer than two distinct x."""
    if len(np.unique(x)) < 2:
        return
    b, a = np.polyfit(x, y, 1)
    xs = np.array([x.min(), x.max()])
    ax.plot(xs, a + b * xs, "--", color=color, lw=1.0, label=f"fit: slope {b:.3g} {slope_unit}")


def sweep_report(out) -> Path:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    out = Path(out)
    if not (out / "results.csv").is_file():
        from ..user_errors import UserError

        where = "does not exist" if not out.exists() else "has no results.csv"
        raise UserError(
            f"sweep-report {out}: the folder {where}: not a sweep's output (run "
            f"`brush-env sweep SPEC --out {out}` first)"
        )
    cols, units, rows = read_table(out / "results.csv")
    info = json.loads((out / "sweep.json").read_text()) if (out / "sweep.json").is_file() else {}
    params = [c for c in cols[3:] if c.split(".")[0] in ("brush", "material", "scene", "motion")]
    metrics = [c for c in cols if c in METRICS and c != "run_time_s"]
    ok = [r for r in rows if r["status"] == "ok"]
    failed = [r for r in rows if r["status"] != "ok"]
    motions = sorted({r["motion"] for r in ok})
    lines = [
        f"# Sweep report: {out.name}",
        "",
        f"{len(rows)} runs ({len(ok)} ok, {len(failed)} failed), motions {motions}; "
        f"executor {info.get('executor', '?')}, sweep wall time "
        f"{info.get('wall_s', float('nan')):.0f} s for {info.get('ran', '?')} runs. "
        "Table: `results.csv` (units in its second row).",
        "",
    ]
    if failed:
        lines += ["Failed runs:", ""] + [f"* `{r['id']}`: {r['error']}" for r in failed] + [""]
    for p in params:
        ncol = min(4, len(metrics))
        nrow = -(-len(metrics) // ncol)
        fig, axs = plt.subplots(
            nrow, ncol, figsize=(2.8 * ncol, 2.4 * nrow), dpi=100, squeeze=False
        )
        for ax in axs.ravel()[len(metrics) :]:
            ax.set_visible(False)
        for ax, m in zip(axs.ravel(), metrics, strict=False):
            for k, mot in enumerate(motions):
                pts = [(r[p], r[m]) for r in ok if r["motion"] == mot and r[m] is not None]
                if pts:
                    x, y = np.array(pts).T
                    ax.plot(x, y, "o", ms=3, color=f"C{k}", label=f"runs, motion {mot}")
                    _fit_line(ax, x, y, f"C{k}", f"{METRICS[m][0]}/{key_unit(p)}")
            ax.set_xlabel(param_words(p), fontsize=7)
            ax.set_title(metric_words(m), fontsize=7)
            ax.tick_params(labelsize=6)
            ax.legend(fontsize=5, loc="best")
        fig.suptitle(
            f"Effect of {param_words(p)} on each metric (one dot per run; dashed: least-squares "
            f"line)\n{p}",
            fontsize=8,
        )
        fig.tight_layout()
        name = f"effect_{p.replace('.', '_').replace('*', 'all')}.png"
        fig.savefig(out / name)
        plt.close(fig)
        lines += [f"![{p}]({name})", ""]
    lines += ["## Sensitivity (standardised regression coefficients)", ""]
    head = "| metric | motion | R² | " + " | ".join(f"SRC {p}" for p in params) + " | ranking |"
    lines += [head, "|" + "---|" * (4 + len(params))]
    findings = []
    for m in metrics:
        for mot in motions:
            sel = [r for r in ok if r["motion"] == mot and r[m] is not None]
            if len(sel) < len(params) + 2:
                continue
            X = np.array([[r[p] for p in params] for r in sel])
            y = np.array([r[m] for r in sel])
            s, r2 = src(X, y)
            order = np.argsort(-np.abs(s))
            rank = " > ".join(params[i].split(".")[-1] for i in order)
            lines.append(
                f"| {m} | {mot} | {r2:.2f} | " + " | ".join(f"{v:+.2f}" for v in s) + f" | {rank} |"
            )
            if m.startswith("peak_"):
                i = order[0]
                findings.append(
                    f"* **{m}** ({mot}): **{params[i]}** moves it most (SRC {s[i]:+.2f}: one "
                    f"standard deviation of it moves the metric by {abs(s[i]):.2f} of its own; "
                    f"R² = {r2:.2f})."
                )
    lines += ["", "## Which parameter moves the peak forces most", ""] + (
        findings or ["(too few successful runs for a ranking)"]
    )
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path
