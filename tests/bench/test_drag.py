"""``bench drag``: a pressed bristle dragged along the plate slides with Coulomb's law of the
paper's Table 2 (|F_t| = mu_d F_n) once it has let go, in both models and both directions (no
timing asserted)."""

from __future__ import annotations

import math

import pytest

from brush_env.bench import drag as D
from brush_env.calibration import FULL_BODIES, FULL_DT
from brush_env.engine import SimSettings, Simulator, load_brush
from brush_env.engine import prb_calibration as pc
from brush_env.engine.scene import ContactParams

NO_G = (0.0, 0.0, 0.0)
MU_D = ContactParams().mu_d  # Table 2


def _outer():
    for _key, (br, lean) in pc.bristle_types(load_brush("default")).items():
        if br.group == "outer":
            return br, lean
    raise AssertionError("the default brush has no outer bristle")


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, 1.0)], ids=["wide", "thin"])
def test_reduced_bristle_slides_at_mu_d(direction):
    br, lean = _outer()
    sim = Simulator(D.bristle_scene(br, lean, 2), SimSettings(dt=4e-3, model="prb", gravity=NO_G))
    r = D.drag_bristle(sim, br.length, direction)
    # it sticks first (the stiction of eq 7-10 holds the tip while the bristle bends), then
    # slides for the rest of the drag, measured over its last MEASURE mm
    assert 0.0 < r["slides_at_mm"] < D.TRAVEL - D.MEASURE
    assert r["fn_N"] > 0.0
    assert r["ft_N"] / r["fn_N"] == pytest.approx(MU_D, rel=1e-2)


@pytest.mark.slow
def test_full_bristle_slides_at_mu_d():
    br, lean = _outer()
    sim = Simulator(D.bristle_scene(br, lean, FULL_BODIES), SimSettings(dt=FULL_DT, gravity=NO_G))
    r = D.drag_bristle(sim, br.length, (0.0, 1.0))
    assert 0.0 < r["slides_at_mm"] < D.TRAVEL - D.MEASURE
    assert r["ft_N"] / r["fn_N"] == pytest.approx(MU_D, rel=2e-2)


def test_tables_name_every_row():
    one = {"fn_N": 0.02, "ft_N": 0.015, "slides_at_mm": 5.0}
    bristles = [
        {
            "bristle": "outer",
            "direction": "thin (y)",
            "full": one,
            "reduced": one,
            "fn_error": 0.0,
            "ft_error": 0.0,
        }
    ]
    brush = [
        {
            "direction": "thin (y)",
            "level": lv,
            "against": "reference",
            "fn_N": 0.3,
            "lateral_N": 0.2,
            "wall_s": 1.0,
            "fn_error": e,
            "lateral_error": e,
        }
        for lv, e in (("reference", 0.0), ("reduced", -0.25))
    ]
    text = D.format_tables(bristles, brush)
    assert "| outer | thin (y) |" in text and "-25.0 %" in text
    assert not math.isnan(bristles[0]["fn_error"])
