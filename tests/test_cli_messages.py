"""The last rough messages of a new user's first day (issue 31): every command-line value is
reported under the name and in the unit the user typed, every named choice gets a did-you-mean,
no raw OS error, one line, exit code 2, and nothing run or written.  A warning never prints its
source line (into a progress bar).

Each case runs the real entry point in this process (``main(argv)``, as the console scripts
do); the first-start compile notice is taken as already shown (it is no part of the message).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import pytest

from brush_env import cli, kernel_cache
from brush_env.user_errors import run_main

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _no_compile_notice(monkeypatch):
    monkeypatch.setattr(kernel_cache, "_announced", True)


def _fails_in_one_line(capsys, main, argv) -> str:
    """Run ``main(argv)``; assert exit code 2 and one stderr line; return that line."""
    try:
        rc = main(argv)
    except SystemExit as e:  # argparse's usage errors exit from inside the parser
        rc = e.code
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert rc == 2, err
    assert len(err) == 1, err
    assert "Traceback" not in err[0] and "Errno" not in err[0]
    return err[0]


def test_pitch_error_is_reported_in_degrees_under_its_flag(capsys, tmp_path):
    out = tmp_path / "out"
    line = _fails_in_one_line(
        capsys, cli.main, ["reference", "--pitch-error", "100", "--out", str(out)]
    )
    assert (
        "brush-env: error: --pitch-error = 100 deg is out of range: must be >= -90 and <= 90 (deg)"
        in line
    )
    assert "alpha_rad" not in line and "rad)" not in line
    assert not out.exists()


def test_a_pitch_window_beyond_a_short_run_is_refused_not_reported_ok(capsys, tmp_path):
    argv = ["reference", "--pitch-error", "1", "--turns", "0.5", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "--pitch-error = 1 deg has no effect with --turns = 0.5 turns" in line
    assert "θ = 360-450° starts after the run ends at θ = 180°; needs --turns >= 1.25" in line


def test_press_depth_is_reported_under_its_flag_in_mm(capsys, tmp_path):
    argv = ["reference", "--press-depth", "15", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "--press-depth = 15 mm is out of range: must be >= 0 and < 10 (mm)" in line


def test_time_step_is_reported_under_its_flag_in_seconds(capsys, tmp_path):
    argv = ["reference", "--dt", "0.5", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "--dt = 0.5 s is out of range: must be > 0 and <= 0.1 (s)" in line


def test_bodies_zero_is_refused_under_its_flag(capsys, tmp_path):
    argv = ["reference", "--bodies", "0", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "--bodies = 0 is out of range: must be >= 1 and <= 200 (bodies per bristle)" in line
    assert "BristleConfig" not in line


def test_misspelt_scene_gets_a_did_you_mean(capsys, tmp_path):
    argv = ["reference", "--scene", "toothrow", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "scene 'toothrow' is not a known scene; did you mean tooth_row?" in line


def test_misspelt_sweep_gets_a_did_you_mean(capsys, tmp_path):
    line = _fails_in_one_line(
        capsys, cli.main, ["sweep", "section_lenght_E", "--out", str(tmp_path / "o")]
    )
    assert "did you mean section_length_E?" in line


def test_misspelt_fidelity_level_gets_a_did_you_mean(capsys, tmp_path):
    argv = ["reference", "--fidelity", "balancd", "--out", str(tmp_path / "o")]
    assert "did you mean balanced?" in _fails_in_one_line(capsys, cli.main, argv)


def test_misspelt_subcommand_choice_gets_a_did_you_mean(capsys):
    line = _fails_in_one_line(capsys, cli.main, ["bench", "engin"])
    assert "invalid choice: 'engin'; did you mean engine?" in line


def test_misspelt_option_choice_gets_a_did_you_mean(capsys, tmp_path):
    argv = ["reference", "--integrator", "eulr", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "argument --integrator: invalid choice: 'eulr'; did you mean euler?" in line


def test_misspelt_env_id_gets_a_did_you_mean(capsys, tmp_path):
    evaluate = pytest.importorskip("agents.evaluate")
    argv = ["--env", "brush_env/ToothRo-v0", "--policy", "reference", "--episodes", "1"]
    line = _fails_in_one_line(capsys, evaluate.main, [*argv, "--out", str(tmp_path / "o")])
    expected = "--env = 'brush_env/ToothRo-v0' is not a registered env; did you mean "
    assert expected + "brush_env/ToothRow-v0? (registered:" in line


def test_sweep_report_on_a_folder_without_results_says_so(capsys, tmp_path):
    line = _fails_in_one_line(capsys, cli.main, ["sweep-report", str(tmp_path)])
    assert f"sweep-report {tmp_path}: the folder has no results.csv: not a sweep's output" in line


def test_sweep_report_on_a_missing_folder_says_so(capsys, tmp_path):
    line = _fails_in_one_line(capsys, cli.main, ["sweep-report", str(tmp_path / "nope")])
    assert "the folder does not exist: not a sweep's output (run `brush-env sweep SPEC" in line


def test_sweep_limit_zero_is_refused_under_its_flag(capsys, tmp_path):
    argv = ["sweep", "section_length_E", "--limit", "0", "--out", str(tmp_path / "o")]
    line = _fails_in_one_line(capsys, cli.main, argv)
    assert "--limit = 0 is out of range: must be >= 1 (variants)" in line
    assert not (tmp_path / "o").exists()


def test_negative_timesteps_blame_only_timesteps(capsys, tmp_path):
    train = pytest.importorskip("agents.train")
    argv = ["--algo", "ppo", "--config", str(ROOT / "configs/agents/ppo.toml"), "--timesteps", "-5"]
    line = _fails_in_one_line(capsys, train.main, [*argv, "--out", str(tmp_path / "o")])
    assert "--timesteps = -5 is out of range: must be >= 1 (env steps)" in line
    assert "--n-envs" not in line


def test_a_warning_is_one_line_above_the_progress_bar(capsys):
    """A PenetrationWarning during a run: one line ``PenetrationWarning: ...`` on stderr, not the
    default two whose second (the ``warnings.warn(`` source line) broke the bar."""
    from tqdm import tqdm

    from brush_env.engine import PenetrationWarning

    def run(argv) -> int:
        with tqdm(total=3, file=sys.stderr, desc="run") as bar:
            bar.update(1)
            warnings.warn("t = 0.1 s: tip of bristle 3 penetrates\n 9 um", PenetrationWarning, 2)
            bar.update(2)
        return 0

    with warnings.catch_warnings():
        warnings.simplefilter("always")  # pytest's config turns RuntimeWarnings into errors
        assert run_main(run, [], prog="brush-env") == 0
    err = capsys.readouterr().err
    text = [ln for ln in err.replace("\r", "\n").splitlines() if "Warning" in ln]
    assert text == ["PenetrationWarning: t = 0.1 s: tip of bristle 3 penetrates 9 um"]
    assert "warnings.warn(" not in err and "test_cli_messages.py" not in err
