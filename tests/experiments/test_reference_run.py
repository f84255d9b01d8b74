"""Tests for brush_env.experiments: the paper's reference experiment end to end.

Peak detection and the analysis helpers on synthetic signals (known peaks at known angles), and
end-to-end runs of ``run_reference`` on the tiny brush (configs/brushes/tiny.toml: 4 bristles x 3
bodies) over a fraction of a turn at a large dt, checking every output file, CSV column and summary
key; the pitch-error run producing both series.
"""

import csv
import json
import math

import numpy as np
import pytest

from brush_env.engine import load_brush
from brush_env.engine.rotation import expmap as _exp_so3
from brush_env.engine.rotation import rotation_vectors
from brush_env.engine.scene import Scene
from brush_env.experiments import (
    CSV_COLUMNS,
    PAPER_JAMMING_ANGLES,
    SUMMARY_KEYS,
    detect_peaks,
    jamming_analysis,
    per_turn_stats,
    pi_label,
    pitch_asymmetry,
    repeatability,
    run_reference,
)
from brush_env.motion import R0

TWO_PI = 2 * math.pi

# quick scenario: short press and hold, faster tool, a fraction of a turn, large dt
QUICK = dict(dt=5e-3, speed=40.0, accel=200.0, press_time=0.2, hold_time=0.05, progress=False)


# ------------------------------------------------------------------------------------------
# synthetic signals
# ------------------------------------------------------------------------------------------
def _two_peaks_per_turn(theta, centres_mod, amp=1.0, width=0.12, base=0.5, noise=0.0, seed=0):
    y = np.full_like(theta, base) + 0.1 * np.sin(theta)
    for k in range(5):
        for c in centres_mod:
            y += amp * np.exp(-0.5 * ((theta - (c + k * TWO_PI)) / width) ** 2)
    if noise:
        y += noise * np.random.default_rng(seed).standard_normal(theta.shape)
    return y


def test_detect_peaks_known_angles():
    theta = np.linspace(0.0, 8 * math.pi, 20001)
    y = _two_peaks_per_turn(theta, (math.pi / 4, 5 * math.pi / 4), noise=0.02)
    peaks = detect_peaks(theta, y, theta_range=(math.pi / 2, 8 * math.pi), n_per_turn=2)
    expected = [c + k * TWO_PI for k in (1, 2, 3) for c in (math.pi / 4, 5 * math.pi / 4)]
    expected += [5 * math.pi / 4]  # turn 1 after the excluded quarter
    assert sorted(p["theta"] for p in peaks) == pytest.approx(sorted(expected), abs=0.02)
    for p in peaks:
        assert p["turn"] == int(p["theta"] // TWO_PI) + 1
        assert p["theta_mod_2pi"] == pytest.approx(p["theta"] % TWO_PI)
        assert p["raw_value"] > 1.3 and p["prominence"] > 0.5
        assert 0 <= p["index"] < theta.size
        assert abs(theta[p["index"]] - p["theta"]) < 0.01


def test_detect_peaks_n_per_turn_keeps_the_most_prominent():
    theta = np.linspace(0.0, 4 * math.pi, 8001)
    y = _two_peaks_per_turn(theta, (math.pi / 4,), amp=1.0)
    y += 0.3 * np.exp(-0.5 * ((theta - (TWO_PI + 1.5 * math.pi)) / 0.1) ** 2)  # small extra bump
    all_peaks = detect_peaks(theta, y, theta_range=(TWO_PI, 4 * math.pi))
    one = detect_peaks(theta, y, theta_range=(TWO_PI, 4 * math.pi), n_per_turn=1)
    assert len(all_peaks) == 2
    assert len(one) == 1 and one[0]["theta"] == pytest.approx(TWO_PI + math.pi / 4, abs=0.01)


def test_detect_peaks_rejects_ramps_flat_and_tiny_signals():
    theta = np.linspace(0.0, 6 * math.pi, 6001)
    assert detect_peaks(theta, theta.copy()) == []  # monotone: no interior maximum
    assert detect_peaks(theta, np.zeros_like(theta)) == []
    tiny = 1e-6 * _two_peaks_per_turn(theta, (math.pi / 4,))
    assert len(detect_peaks(theta, tiny)) > 0  # relative threshold alone: found
    assert detect_peaks(theta, tiny, min_abs_prominence=1e-3) == []  # below 1 mN: no jamming
    with pytest.raises(ValueError):
        detect_peaks(theta, theta[:-1])


def test_jamming_analysis_maps_peaks_to_the_paper_angles():
    theta = np.linspace(0.0, 8 * math.pi, 16001)
    shift = 0.2  # rad later than the paper
    fh = _two_peaks_per_turn(theta, (math.pi / 4 + shift, 5 * math.pi / 4 + shift))
    ang = 0.3 * theta  # split F_h into components: |F_h| is what is detected
    F = np.stack([fh * np.cos(ang), fh * np.sin(ang), -2.0 + 0 * theta], axis=1)
    jam = jamming_analysis(theta, F, theta_range=(math.pi / 2, 8 * math.pi))
    assert {p["nearest_paper_angle"] for p in jam["peaks"]} == {"9π/4", "13π/4"}
    for name, paper in zip(("9π/4", "13π/4"), PAPER_JAMMING_ANGLES):
        ev = jam["events"][name]
        assert ev["count"] >= 3
        assert ev["mean_offset_from_paper_deg"] == pytest.approx(math.degrees(shift), abs=1.0)
        assert ev["mean_angle_mod_2pi_deg"] == pytest.approx(
            math.degrees(paper % TWO_PI + shift), abs=1.0
        )
        assert ev["angle_std_deg"] < 1.0
    for p in jam["peaks"]:
        assert p["Fz_N"] == pytest.approx(-2.0)
        assert math.hypot(p["Fx_N"], p["Fy_N"]) == pytest.approx(p["Fh_N"], rel=0.05)


def test_per_turn_stats_and_repeatability_on_identical_turns():
    theta = np.linspace(0.0, 8 * math.pi, 16001)
    F = np.stack([np.cos(theta + 0.3), 2 * np.sin(theta), -3 + 0.5 * np.cos(2 * theta)], axis=1)
    rows = per_turn_stats(theta, F, theta_range=(math.pi / 2, 8 * math.pi))
    assert [r["turn"] for r in rows] == [1, 2, 3, 4]
    assert [r["complete"] for r in rows] == [False, True, True, True]
    for r in rows[1:]:
        assert r["Fy_max_N"] == pytest.approx(2.0, abs=1e-4)
        assert r["Fy_max_theta_mod_2pi_deg"] == pytest.approx(90.0, abs=0.1)
        assert r["Fy_min_theta_mod_2pi_deg"] == pytest.approx(270.0, abs=0.1)
        assert r["Fz_mean_N"] == pytest.approx(-3.0, abs=1e-3)
        assert r["Fh_max_N"] >= r["Fy_max_N"] - 1e-9
    rep = repeatability(theta, F, rows)
    assert rep["turns"] == [2, 3, 4]
    for c in ("Fx", "Fy", "Fz", "Fh"):
        assert rep["trace_rms_spread_N"][c] < 1e-3
        assert rep["mean_std_N"][c] < 1e-3
    assert rep["trace_rms_N"]["Fy"] == pytest.approx(math.sqrt(2.0), rel=1e-2)
    # one turn different: the spread shows it
    F2 = F.copy()
    F2[(theta > 4 * math.pi) & (theta < 6 * math.pi), 1] *= 1.5
    rows2 = per_turn_stats(theta, F2, theta_range=(math.pi / 2, 8 * math.pi))
    rep2 = repeatability(theta, F2, rows2)
    assert rep2["trace_rms_spread_N"]["Fy"] > 0.2 and rep2["peak_cv"]["Fy"] > 0.1
    # fewer than two complete turns >= 2: no repeatability numbers
    short = repeatability(theta, F, [r for r in rows if r["turn"] <= 2])
    assert short["trace_rms_spread_N"] is None


def test_pitch_asymmetry_on_a_known_change():
    theta = np.linspace(0.0, 6 * math.pi, 12001)
    Fb = np.stack([np.cos(theta), 2 * np.sin(theta - 0.5), -3 + 0 * theta], axis=1)
    Fp = Fb.copy()
    win = (TWO_PI, 2.5 * math.pi)
    m = (theta >= win[0]) & (theta <= win[1])
    Fp[m, 1] *= 0.8  # 20 % lower Fy in the window
    res = pitch_asymmetry(theta, Fb, Fp, win, pitch=np.where(m, 0.01, 0.0))
    ch = res["change"]
    assert ch["Fy_max_N"]["change_percent"] == pytest.approx(-20.0, abs=0.01)
    assert ch["absFy_peak_N"]["pitch"] == pytest.approx(0.8 * ch["absFy_peak_N"]["baseline"])
    assert ch["Fx_over_Fy_peak_ratio"]["change_percent"] == pytest.approx(25.0, abs=0.01)
    assert ch["absFx_peak_N"]["change"] == pytest.approx(0.0)
    assert res["turn_to_turn"]["baseline"]["absFy_peak_ratio_window_to_next_turn"] == pytest.approx(
        1.0, abs=1e-3
    )
    assert res["turn_to_turn"]["pitch"]["absFy_peak_ratio_window_to_next_turn"] == pytest.approx(
        0.8, abs=1e-3
    )
    assert res["rms_difference_N"]["after_window"]["y"] == pytest.approx(0.0, abs=1e-12)
    assert res["rms_difference_N"]["window"]["y"] > 0.1
    assert res["pitch_peak_deg"] == pytest.approx(math.degrees(0.01))


def test_rotation_vectors_and_pi_labels():
    rv = rotation_vectors(np.array([R0, np.eye(3)]))
    assert rv[0] == pytest.approx([math.pi, 0, 0]) or rv[0] == pytest.approx([-math.pi, 0, 0])
    assert rv[1] == pytest.approx([0, 0, 0])
    # a small pitch on top of R0: continuous, exp(rv) reproduces R
    phis = np.linspace(0.0, math.radians(1.0), 50)
    Rs = np.array([np.array(R0) @ _exp_so3(np.array([0.0, p, 0.0])) for p in phis])
    rv = rotation_vectors(Rs)
    assert np.max(np.abs(np.diff(rv, axis=0))) < 0.01
    assert np.allclose(_exp_so3(rv), Rs, atol=1e-9)
    assert [pi_label(a) for a in PAPER_JAMMING_ANGLES] == ["9π/4", "13π/4"]
    assert pi_label(2 * math.pi) == "2π" and pi_label(math.pi / 2) == "π/2" and pi_label(0) == "0"


# ------------------------------------------------------------------------------------------
# end to end on the tiny brush
# ------------------------------------------------------------------------------------------
def _read_csv(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array(rows[1:], dtype=float)


def _check_outputs(out, summary, nb, pitch=False):
    """Every output file of a reference run in ``out`` and the returned ``summary`` (a brush of
    ``nb`` bristles; ``pitch``: with a pitch run); returns the timeseries columns."""
    _check_files(out, summary, pitch)
    col = _check_timeseries(out / "timeseries.csv", nb)
    _check_tips(out / "tips.npz", nb)
    _check_summary(summary, nb, col)
    return col


def _check_files(out, summary, pitch):
    for name in (
        "timeseries.csv",
        "tips.npz",
        "forces_vs_angle.png",
        "deformed_shapes.png",
        "summary.json",
    ):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    # the pitch comparison (Figure 10) has its own file and leaves Figure 7 alone
    assert (out / "forces_vs_angle_pitch.png").is_file() == pitch
    with open(out / "summary.json") as f:
        assert json.load(f) == summary
    for key in SUMMARY_KEYS:
        assert key in summary, key


def _check_timeseries(path, nb):
    header, data = _read_csv(path)
    assert tuple(header) == CSV_COLUMNS
    assert data.shape[1] == len(CSV_COLUMNS) and data.shape[0] > 10
    col = {c: data[:, i] for i, c in enumerate(header)}
    assert np.all(np.diff(col["time_s"]) > 0)
    assert set(np.unique(col["phase"])) <= {0, 1, 2}
    assert col["theta_rad"][0] == 0 and np.all(np.diff(col["theta_rad"]) >= -1e-12)
    assert np.all(np.isfinite(data))
    assert col["Fh_N"] == pytest.approx(np.hypot(col["Fx_N"], col["Fy_N"]), abs=1e-6)
    assert np.all(col["n_contact"] <= nb) and np.all(col["max_penetration_mm"] >= 0)
    return col


def _check_tips(path, nb):
    with np.load(path) as z:
        for k in (
            "time",
            "theta",
            "tip_pos",
            "tip_vel",
            "tip_normal_force",
            "tip_tangential_force",
            "tip_contact_force",
            "tip_in_contact",
            "tip_penetration",
            "shape_body_pos",
            "shape_tip_pos",
            "shape_root_pos",
            "bstart",
            "group",
        ):
            assert k in z.files, k
        M = z["time"].shape[0]
        assert z["tip_pos"].shape == (M, nb, 3) and z["tip_vel"].shape == (M, nb, 3)
        assert z["tip_normal_force"].shape == (M, nb)
        assert z["tip_contact_force"].shape == (M, nb, 3)
        assert z["shape_body_pos"].shape[1] == int(z["bstart"][-1])


def _check_summary(s, nb, col):
    st = s["settings"]
    for k in (
        "brush",
        "material",
        "dt_s",
        "bodies",
        "integrator",
        "speed_mm_s",
        "accel_mm_s2",
        "path",
        "turns",
        "press_depth_mm",
        "pitch_error_deg",
        "head_yaw_deg",
        "p0_angle_deg",
        "clockwise",
        "max_substep_s",
    ):
        assert k in st, k
    assert st["brush"]["name"] == "tiny" and st["brush"]["n_bristles"] == nb
    assert st["brush"]["file"].endswith("tiny.toml")
    assert st["material"][0]["name"] == "silicone_7MPa"
    assert st["bodies"] == [3]
    for k in ("wall_time_s", "sim_wall_time_s", "simulated_time_s", "real_time_factor"):
        assert s["performance"][k] > 0, k
    assert s["trajectory"]["movel"]["deviation_from_circle"]["max_abs_mm"] == pytest.approx(
        1.213, abs=2e-3
    )
    a = s["analysis"]["baseline"]
    for k in ("per_turn", "jamming", "repeatability", "max_penetration_mm", "theta_range_rad"):
        assert k in a, k
    assert a["theta_range_rad"][0] == pytest.approx(math.pi / 2)
    if col["theta_rad"][-1] <= math.pi / 2:  # (a run stopped early by a divergence)
        assert a["per_turn"] == [] and a["jamming"] is None
        return
    assert len(a["per_turn"]) >= 1
    for k in ("Fx_max_N", "Fx_max_theta_rad", "Fy_min_N", "Fz_mean_N", "Fh_max_N"):
        assert k in a["per_turn"][0]


def _free_scene(brush="tiny"):
    """A scene without surfaces: pure kinematics and gravity, independent of the contact model."""
    return Scene(load_brush(brush), (), False, "free")


def test_reference_end_to_end_tiny(tmp_path):
    out = tmp_path / "ref"
    s = run_reference(brush="tiny", out_dir=out, turns=0.3, **QUICK)
    col = _check_outputs(out, s, nb=4)  # every file, column and key, also after a divergence
    z = col["z_mm"]
    assert z[0] == pytest.approx(s["trajectory"]["touch_tcp_z_mm"])
    assert s["status"] == "ok", s["run_status"]
    # the press reached 3 mm and the tips touched the plate
    assert z[0] - z.min() == pytest.approx(3.0, abs=1e-6)  # CSV keeps 9 significant digits
    assert col["n_contact"].max() > 0 and np.max(-col["Fz_N"]) > 0.01
    assert col["theta_rad"][-1] == pytest.approx(0.3 * TWO_PI, abs=0.02)
    assert s["trajectory"]["cut_before_end_of_motion"] is True


def test_reference_pitch_error_produces_both_series(tmp_path):
    out = tmp_path / "pitch"
    win = (0.55 * math.pi, 0.8 * math.pi)  # inside the short run (the paper's is [2π, 5π/2])
    s = run_reference(
        scene=_free_scene(), out_dir=out, turns=0.45, pitch_error_deg=1.0, pitch_window=win, **QUICK
    )
    assert s["run_status"] == {"baseline": "ok", "pitch": "ok"}
    _check_outputs(out, s, nb=4, pitch=True)
    for name in ("timeseries_pitch.csv", "tips_pitch.npz"):
        assert (out / name).is_file()
    hb, db = _read_csv(out / "timeseries.csv")
    hp, dp = _read_csv(out / "timeseries_pitch.csv")
    assert hp == hb and dp.shape == db.shape
    cb = {c: db[:, i] for i, c in enumerate(hb)}
    cp = {c: dp[:, i] for i, c in enumerate(hp)}
    assert np.array_equal(cb["time_s"], cp["time_s"])
    assert np.array_equal(cb["theta_rad"], cp["theta_rad"])
    inwin = (cp["theta_rad"] > win[0]) & (cp["theta_rad"] < win[1])
    before = cp["theta_rad"] <= win[0]
    assert np.all(cb["pitch_rad"] == 0)
    assert np.max(cp["pitch_rad"]) == pytest.approx(math.radians(1.0), rel=1e-3)
    assert np.max(np.abs(cp["pitch_rad"][~inwin])) < 1e-12
    # identical before the perturbation (shared prefix), different inside it: the pitched brush
    # tilts (rotation vector) and its weight acts with another lever arm (moment about the TCP)
    for c in ("Fx_N", "Fy_N", "Fz_N", "Mx_Nmm", "My_Nmm", "Mz_Nmm", "rx_rad", "ry_rad", "rz_rad"):
        assert np.array_equal(cb[c][before], cp[c][before]), c
    drv = np.stack([cp[c][inwin] - cb[c][inwin] for c in ("rx_rad", "ry_rad", "rz_rad")])
    assert np.max(np.linalg.norm(drv, axis=0)) > 0.5 * math.radians(1.0)
    dM = np.stack([cp[c][inwin] - cb[c][inwin] for c in ("Mx_Nmm", "My_Nmm", "Mz_Nmm")])
    assert np.max(np.abs(dM)) > 1e-5
    asym = s["analysis"]["pitch_asymmetry"]
    assert asym["window_rad"] == pytest.approx(list(win))
    for k in ("Fy_max_N", "absFy_peak_N", "Fx_over_Fy_peak_ratio"):
        assert set(asym["change"][k]) >= {"baseline", "pitch", "change", "change_percent"}
    assert asym["pitch_peak_deg"] == pytest.approx(1.0, rel=1e-3)
    assert "pitch" in s["analysis"]
    assert s["performance"]["runs"]["pitch"]["shared_prefix_steps"] > 0


def test_reference_cli_free_brush(tmp_path):
    """The CLI wiring, on a scene without surfaces (pure kinematics, no contact)."""
    from brush_env import cli

    scene = tmp_path / "free.toml"
    scene.write_text('name = "free"\nbrush = "tiny"\ntip_tip = false\n')
    out = tmp_path / "cli"
    rc = cli.main(
        [
            "reference",
            "--scene",
            str(scene),
            "--out",
            str(out),
            "--turns",
            "0.3",
            "--dt",
            "0.01",
            "--speed",
            "40",
            "--accel",
            "200",
            "--path",
            "circle",
            "--bodies",
            "2",
            "--integrator",
            "euler",
            "--no-progress",
        ]
    )
    assert rc == 0
    s = json.loads((out / "summary.json").read_text())
    st = s["settings"]
    assert st["path"] == "circle" and st["bodies"] == [2] and st["integrator"] == "euler"
    assert st["dt_s"] == 0.01 and st["speed_mm_s"] == 40 and st["scene"]["name"] == "free"
    assert "movel" not in s["trajectory"]
    # no contact: no jamming peaks, the robot carries the brush's weight
    assert s["analysis"]["baseline"]["jamming"]["peaks"] == []
    _, data = _read_csv(out / "timeseries.csv")
    assert np.all(data[:, CSV_COLUMNS.index("n_contact")] == 0)
    weight = 2 * 1.15e-9 * 9810 * 0.8 * (1.8 * 9 + 1.3 * 10)  # t/mm^3 * mm/s^2 * mm^3 = N
    assert np.median(data[:, CSV_COLUMNS.index("Fz_N")]) == pytest.approx(weight, rel=0.05)


def test_run_reference_rejects_bad_input(tmp_path):
    with pytest.raises(ValueError, match="turns"):
        run_reference(brush="tiny", out_dir=tmp_path, turns=0, progress=False)
    with pytest.raises(ValueError, match="dt"):
        run_reference(brush="tiny", out_dir=tmp_path, dt=-1, progress=False)
    with pytest.raises(ValueError, match="path"):
        run_reference(
            brush="tiny", out_dir=tmp_path, turns=0.1, path="square", progress=False, plots=False
        )


def test_tiny_brush_config():
    b = load_brush("tiny")
    assert b.n_bristles == 4 and {x.bodies for x in b.bristles} == {3}
    assert isinstance(Scene(b), Scene)
