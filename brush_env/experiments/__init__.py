"""brush_env.experiments: the paper's circular UR5 reference experiment (``brush-env reference``).

Modules, in the order a run uses them: ``plan`` (defaults, scene, touch height, the motion and
its time grid), ``record`` (simulate and record), ``analysis`` (peaks, jamming, per-turn
statistics, repeatability, pitch asymmetry), ``outputs`` (CSV, NPZ, summary.json), ``plots``
(Figures 7, 9, 10), ``run`` (``run_reference``: the stages in order), ``cli``.
Sits above the engine and the motion package; matplotlib and tqdm are used here, never in the
engine.  See docs/reference_experiment.md.
"""

from .analysis import (
    PAPER_JAMMING_ANGLES,
    TWO_PI,
    analyse_run,
    detect_peaks,
    jamming_analysis,
    per_turn_stats,
    pi_label,
    pitch_asymmetry,
    repeatability,
)
from .cli import add_arguments, run
from .outputs import CSV_COLUMNS, FORCE_CONVENTION, SUMMARY_KEYS
from .plan import DEFAULTS, build_trajectory
from .plots import plot_deformed_shapes, plot_forces_vs_angle
from .run import run_reference

__all__ = [
    "CSV_COLUMNS",
    "DEFAULTS",
    "FORCE_CONVENTION",
    "PAPER_JAMMING_ANGLES",
    "SUMMARY_KEYS",
    "TWO_PI",
    "add_arguments",
    "analyse_run",
    "build_trajectory",
    "detect_peaks",
    "jamming_analysis",
    "per_turn_stats",
    "pi_label",
    "pitch_asymmetry",
    "plot_deformed_shapes",
    "plot_forces_vs_angle",
    "repeatability",
    "run",
    "run_reference",
]
