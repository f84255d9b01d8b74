"""Design sweeps for toothbrush designers (issue 16): ``brush-env sweep SPEC --out DIR`` and
``brush-env sweep-report DIR``.

``spec.py`` (the spec and its checks, sampling), ``run.py`` (one run: variant files, the reference
experiment, metrics), ``executors.py`` (local process pool, Ray), ``sweep.py`` (prepare, resume,
run, the results table), ``safety.py`` (lock, atomic writes, workers that stop with the sweep),
``report.py`` (effects and sensitivity), ``cli.py`` (the commands).
"""

from .report import sweep_report
from .safety import SweepLocked
from .spec import METRICS, load_spec
from .sweep import read_table, run_sweep

__all__ = ["METRICS", "SweepLocked", "load_spec", "read_table", "run_sweep", "sweep_report"]
