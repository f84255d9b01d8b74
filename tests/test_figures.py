"""Every figure the package writes explains itself (issue 31): a legend entry for each marker and
colour, labels that do not overlap, the phase lines named, panel titles in words with units and
fit lines, and the jamming angles the figures quote equal to the ones the run prints.

The figures are the real ones: each test runs the code that writes them and catches every
``Figure.savefig`` on its way to the file (``saved``), then reads the figure's artists and, for
overlaps, their drawn extents from matplotlib's renderer.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from brush_env.experiments.analysis import jamming_analysis  # noqa: E402
from brush_env.experiments.plots import _shape_events, mean_angle_text  # noqa: E402

TWO_PI = 2 * math.pi
#: the tooth-row experiment in a few seconds (tests/experiments/test_tooth_row.py)
TEETH_QUICK = dict(strokes=1, x_range=(-2.0, 2.0), press_time=0.2, hold_time=0.05, dt=2e-3)


@pytest.fixture
def saved(monkeypatch) -> dict:
    """File name -> the Figure saved there, for every figure written while the test runs."""
    figures: dict[str, Figure] = {}
    save = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        figures[Path(fname).name] = self
        return save(self, fname, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return figures


def _legend_labels(fig) -> list[str]:
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    return [t.get_text() for lg in legends for t in lg.get_texts()]


@pytest.fixture(scope="module")
def tooth_row_figures(tmp_path_factory) -> dict:
    from brush_env.experiments.tooth_row import run_tooth_row

    mp = pytest.MonkeyPatch()
    figures: dict[str, Figure] = {}
    save = Figure.savefig

    def savefig(self, fname, *args, **kwargs):
        figures[Path(fname).name] = self
        return save(self, fname, *args, **kwargs)

    mp.setattr(Figure, "savefig", savefig)
    import brush_env.viz.tooth_row as viz

    make = viz.tooth_row_figure

    def tooth_row_figure(*args, **kwargs):
        figures["tooth_row_figure args"] = (args, kwargs)  # to draw it again at other sizes
        return make(*args, **kwargs)

    mp.setattr(viz, "tooth_row_figure", tooth_row_figure)
    try:
        out = tmp_path_factory.mktemp("teeth")
        s = run_tooth_row(brush="tiny", out_dir=out, progress=False, **TEETH_QUICK)
    finally:
        mp.undo()
    assert s["status"] == "ok"
    return figures


def test_coverage_png_has_a_legend_for_every_colour_and_marker(tooth_row_figures):
    labels = _legend_labels(tooth_row_figures["coverage.png"])
    for words in (
        "crown surface cleaned",
        "crown surface not cleaned yet",
        "root surface below the CEJ",
        "bristle whose tip carries load",
        "bristle with a free tip",
        "loaded tip (buccal view)",
    ):
        assert any(lab.startswith(words) for lab in labels), (words, labels)


@pytest.mark.parametrize("height, legend", [(480, True), (360, False), (256, False)])
def test_tooth_row_labels_do_not_overlap(tooth_row_figures, height, legend):
    """The 3-D view's y and z labels and the map's labels were drawn over each other: in
    coverage.png (480 px, with its legend) and in ToothRow-v0's frames (256 px by default)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from brush_env.viz.tooth_row import tooth_row_figure

    if height == 480:
        fig = tooth_row_figures["coverage.png"]  # the file as written
    else:
        args, kwargs = tooth_row_figures["tooth_row_figure args"]
        fig = tooth_row_figure(*args[:4], height, kwargs.get("title", ""), legend=legend)
    canvas = FigureCanvasAgg(fig)  # (the saved figure was closed: draw it again, as saved)
    canvas.draw()
    renderer = canvas.get_renderer()
    ax3d, ax2 = fig.axes
    texts = {
        "3-D x label": ax3d.xaxis.label,
        "3-D y label": ax3d.yaxis.label,
        "3-D z label": ax3d.zaxis.label,
        "map x label": ax2.xaxis.label,
        "map y label": ax2.yaxis.label,
        "map title": ax2.title,
    }
    boxes = {name: t.get_window_extent(renderer) for name, t in texts.items()}
    if legend:
        boxes["legend"] = fig.legends[0].get_window_extent(renderer)
    for (a, ba), (b, bb) in itertools.combinations(boxes.items(), 2):
        assert not ba.overlaps(bb), f"{a} overlaps {b}"
    page = fig.bbox
    for name, box in boxes.items():  # and each lies on the page
        assert page.x0 <= box.x0 and box.x1 <= page.x1 and page.y0 <= box.y0, name
    assert boxes["map title"].y1 <= page.y1


def test_forces_vs_time_names_its_phase_lines(tooth_row_figures):
    fig = tooth_row_figures["forces_vs_time.png"]
    (ax,) = fig.axes
    press, hold = TEETH_QUICK["press_time"], TEETH_QUICK["hold_time"]
    dashed = sorted(
        ln.get_xdata()[0] for ln in ax.lines if ln.get_linestyle() == "--" and len(ln.get_xdata())
    )
    assert dashed == pytest.approx([press, press + hold])
    named = {round(t.xy[0], 6): t.get_text() for t in ax.texts}
    assert named == {round(press, 6): "hold starts", round(press + hold, 6): "strokes starts"}
    assert any(lab.startswith("phase change") for lab in _legend_labels(fig))


def test_phase_labels_do_not_overlap_on_a_long_run(saved, tmp_path):
    """The default run: phases 0.25 s apart on a 6.6 s axis; their names must stay apart."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from brush_env.experiments.tooth_row import _plot_forces

    t = np.arange(1, 6601) * 1e-3
    rows = np.zeros((t.size, 12))
    rows[:, 0], rows[:, 4] = t, np.sin(t)
    _plot_forces(tmp_path / "forces_vs_time.png", rows, (0.0, 0.5, 0.75))
    fig = saved["forces_vs_time.png"]
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    a, b = (x.get_window_extent(canvas.get_renderer()) for x in fig.axes[0].texts)
    assert not a.overlaps(b)


def test_the_figures_quote_the_jamming_angle_the_run_prints():
    """deformed_shapes.png's peak labels carry the event's mean angle in the very words the run
    prints (``mean_angle_text``), beside the shown peak's own angle (they differ: 53 vs 54)."""
    theta = np.linspace(0.0, 8 * math.pi, 16001)
    fh = np.full_like(theta, 0.5)
    for k in range(5):  # peaks drifting turn to turn: their mean is not the shown turn's angle
        for c in (math.pi / 4 + 0.16 + 0.01 * k, 5 * math.pi / 4 + 0.16):
            fh += np.exp(-0.5 * ((theta - (c + k * TWO_PI)) / 0.12) ** 2)
    F = np.stack([fh, 0 * theta, -2.0 + 0 * theta], axis=1)
    jam = jamming_analysis(theta, F, theta_range=(math.pi / 2, 8 * math.pi))
    events = _shape_events({"jamming": jam}, math.pi / 2, 8 * math.pi)
    assert len(events) == 2
    for (_, label), name in zip(events, ("9π/4", "13π/4")):
        ev = jam["events"][name]
        printed = f"mean angle {mean_angle_text(ev)}"  # brush_env.experiments.cli's line
        assert label.startswith(f"paper's {name} jamming: our turn-2 peak at θ = ")
        assert label.endswith(f"mean of {ev['count']} turn(s): {mean_angle_text(ev)}")
        assert printed.split("mean angle ")[1] in label


def test_deformed_shapes_legend_explains_dots_squares_and_arrow_scale(saved, tmp_path):
    from brush_env.experiments import run_reference

    quick = dict(dt=5e-3, speed=40.0, accel=200.0, press_time=0.2, hold_time=0.05)
    run_reference(brush="tiny", out_dir=tmp_path, turns=0.6, progress=False, **quick)
    labels = _legend_labels(saved["deformed_shapes.png"])
    for words in ("tip in contact", "tip not in contact", "bristle root (top view)"):
        assert words in labels, labels
    arrow = next(lab for lab in labels if lab.startswith("TCP velocity"))
    assert "mm of arrow = 40 mm/s" in arrow  # the tool speed: one scale for every panel
    speeds = [t.get_text() for ax in saved["deformed_shapes.png"].axes for t in ax.texts]
    assert "40 mm/s" in speeds


def test_sweep_report_panels_are_titled_in_words_with_units_and_fit_lines(saved, tmp_path):
    """A table with a known linear effect: peak_Fh_N = 0.1 E + 0.2: the panel says what the
    metric is in words and units, and its fit line has the slope 0.1 N/MPa."""
    from brush_env.sweeps.report import sweep_report

    rows = [
        f"circle_{i:04d},circle,ok,{E!r},{0.1 * E + 0.2!r},{2.0 + i!r},"
        for i, E in enumerate([5.0, 6.0, 7.5, 9.0])
    ]
    (tmp_path / "results.csv").write_text(
        "id,motion,status,material.E_MPa,peak_Fh_N,run_time_s,error\n"
        "# unit,,,MPa,N,s,\n" + "\n".join(rows) + "\n"
    )
    sweep_report(tmp_path)
    fig = saved["effect_material_E_MPa.png"]
    ax = fig.axes[0]
    title = " ".join(ax.get_title().split())  # wrapped to the panel's width
    assert title == "peak horizontal TCP force (turns after the first quarter) [N]"
    assert "peak_Fh_N" not in ax.get_title()
    assert ax.get_xlabel() == "Young's modulus E [MPa]"
    fit = next(ln for ln in ax.lines if ln.get_label().startswith("fit: slope"))
    x, y = fit.get_xdata(), fit.get_ydata()
    assert (y[1] - y[0]) / (x[1] - x[0]) == pytest.approx(0.1)
    assert fit.get_label() == "fit: slope 0.1 N/MPa"
