"""Sweep specs (``configs/sweeps/*.toml``): what to vary, how to sample it, which motions to run and
which metrics to keep -- parsed and checked completely before any run starts (issue 16).

A spec::

    name = "section_length_E"
    brush = "default"                 # a name in configs/brushes or a path
    scene = "flat_plate"
    fidelity = "balanced"             # configs/fidelity level of every run
    seed = 0                          # the sample's seed (lhs, sobol)
    motions = ["circle"]              # circle (the paper's experiment), press, pitch
    metrics = ["peak_Fh_N", "peak_Fz_N", "mean_Fn_N"]   # METRICS keys (default: all)

    [sample]
    method = "lhs"                    # grid (every combination of `values`), lhs, sobol
    n = 12                            # samples (lhs, sobol)

    [motion]                          # run_reference keywords shared by every run
    turns = 2

    [[vary]]
    key = "brush.sections.*.width_mm" # a dotted path; * = every entry of a table or list
    range = [1.0, 2.0]                # [lo, hi] (lhs, sobol) ...
    unit = "mm"                       # optional; must be the key's unit
    [[vary]]
    key = "material.E_MPa"
    values = [5.0, 7.0, 9.0]          # ... or the values (grid)

Keys: ``brush.<path>`` into the brush file, ``material.<key>`` into its material's entry of the
materials file, ``scene.<path>`` into the scene file (e.g. ``scene.contact.mu_s``),
``motion.<name>`` a keyword of ``run_reference`` (``MOTION_UNITS``).  Units come from the key's
suffix (``_mm``, ``_deg``, ``_MPa``, ...) or ``MOTION_UNITS``.  Every error is one line naming
the spec file, the entry, the value and what is allowed.
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import tomllib

from ..engine.checks import ConfigError, did_you_mean
from ..engine.config_files import materials_path, read_toml, resolve_config

MOTIONS = ("circle", "press", "pitch")
#: run_reference keywords a spec may vary or set, with their units
MOTION_UNITS = {
    "turns": "turns",
    "speed": "mm/s",
    "accel": "mm/s^2",
    "radius": "mm",
    "press_depth": "mm",
    "press_time": "s",
    "hold_time": "s",
    "dt": "s",
    "head_yaw_deg": "deg",
    "p0_angle_deg": "deg",
}
#: metric -> (unit, meaning); computed by ``brush_env.sweeps.run.metrics``
METRICS = {
    "peak_Fh_N": ("N", "peak horizontal TCP force (turns after the first quarter)"),
    "peak_Fz_N": ("N", "peak |vertical TCP force|"),
    "mean_Fz_N": ("N", "mean vertical TCP force"),
    "mean_Fn_N": ("N", "mean total normal force on the tips"),
    "peak_Fn_N": ("N", "peak total normal force on the tips (press included)"),
    "mean_Ft_N": ("N", "mean total |tangential| force on the tips"),
    "jam1_angle_deg": ("deg", "first jamming peak's mean angle mod 360 (paper 45)"),
    "jam1_peak_N": ("N", "first jamming peak's mean |F_h|"),
    "jam2_angle_deg": ("deg", "second jamming peak's mean angle mod 360 (paper 225)"),
    "jam2_peak_N": ("N", "second jamming peak's mean |F_h|"),
    "max_penetration_mm": ("mm", "largest tip penetration"),
    "tip_load_spread": ("-", "std / mean over tips of each tip's time-mean normal force"),
    "run_time_s": ("s", "wall time of the run (not in the bit-identical summaries)"),
}
#: the metrics measured on the circle after its first quarter (theta >= pi/2): n/a for ``press``
CIRCLE_METRICS = ("peak_Fh_N", "peak_Fz_N", "mean_Fz_N", "mean_Fn_N",
                  "jam1_angle_deg", "jam1_peak_N", "jam2_angle_deg", "jam2_peak_N")  # fmt: skip
_SUFFIX_UNITS = (
    ("_mm", "mm"),
    ("_deg", "deg"),
    ("_MPa", "MPa"),
    ("_t_per_mm3", "t/mm^3"),
    ("_N", "N"),
    ("_s", "s"),
)
_SPEC_KEYS = ("name", "brush", "scene", "fidelity", "seed", "motions", "metrics", "sample",
              "motion", "vary")  # fmt: skip


def key_unit(key: str) -> str:
    """The unit of a varied key, from MOTION_UNITS or its suffix ('-' for dimensionless)."""
    if key.startswith("motion."):
        return MOTION_UNITS.get(key.split(".", 1)[1], "?")
    last = key.rsplit(".", 1)[-1]
    if last == "E":
        return "MPa"
    for suf, unit in _SUFFIX_UNITS:
        if last.endswith(suf):
            return unit
    return "-"


@dataclass(frozen=True)
class Param:
    key: str
    values: tuple = ()
    lo: float | None = None
    hi: float | None = None

    @property
    def unit(self) -> str:
        return key_unit(self.key)


@dataclass(frozen=True)
class SweepSpec:
    """A checked spec: ``points`` (n_runs, n_params) holds every run's values."""

    path: Path
    name: str
    brush: str
    scene: str
    fidelity: str
    seed: int
    motions: tuple
    metrics: tuple
    method: str
    params: tuple
    motion: dict = field(default_factory=dict)
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    def runs(self) -> list[dict]:
        """Every run as {id, motion, params: {key: value}} in a fixed order."""
        out = []
        for mot in self.motions:
            for i, row in enumerate(self.points):
                out.append(
                    dict(
                        id=f"{mot}_{i:04d}",
                        motion=mot,
                        params={p.key: float(v) for p, v in zip(self.params, row, strict=True)},
                    )
                )
        return out


def _fail(path, where, msg):
    raise ConfigError(f"{path}: {where}: {msg}")


def load_spec(path) -> SweepSpec:
    """Parse and check a spec (module docstring); nothing is run."""
    path = resolve_config("sweep", path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None
    motions, metrics, motion, sample, method, seed = _top_level(path, data)
    bases = base_tables(path, data)
    vary = data.get("vary", [])
    if not vary:
        _fail(path, "[[vary]]", "empty: name at least one parameter to vary")
    params = [_vary(path, f"[[vary]] #{j + 1}", t, bases) for j, t in enumerate(vary)]
    points = _sample(path, method, sample, params, seed)
    return SweepSpec(
        path=path,
        name=str(data.get("name", path.stem)),
        brush=str(data.get("brush", "default")),
        scene=str(data.get("scene", "flat_plate")),
        fidelity=str(data.get("fidelity", "balanced")),
        seed=seed,
        motions=motions,
        metrics=metrics,
        method=method,
        params=tuple(params),
        motion=motion,
        points=points,
    )


def _top_level(path, data) -> tuple:
    """The checked top-level keys: (motions, metrics, [motion], [sample], method, seed)."""
    for k in data:
        if k not in _SPEC_KEYS:
            _fail(path, f"key {k!r}", f"unknown{did_you_mean(k, _SPEC_KEYS)}")
    motions = tuple(data.get("motions", ["circle"]))
    for m in motions:
        if m not in MOTIONS:
            _fail(path, "motions", f"{m!r} is not one of {list(MOTIONS)}")
    if not motions:
        _fail(path, "motions", "empty: name at least one of " + str(list(MOTIONS)))
    metrics = tuple(data.get("metrics", list(METRICS)))
    for m in metrics:
        if m not in METRICS:
            _fail(path, "metrics", f"{m!r} is unknown{did_you_mean(m, METRICS)}")
    motion = dict(data.get("motion", {}))
    for k, v in motion.items():
        if k not in MOTION_UNITS:
            _fail(
                path, f"[motion] {k}", f"not a run_reference keyword{did_you_mean(k, MOTION_UNITS)}"
            )
        if not (isinstance(v, (int, float)) and math.isfinite(v)):
            _fail(path, f"[motion] {k}", f"{v!r} must be a finite number ({MOTION_UNITS[k]})")
    sample = dict(data.get("sample", {}))
    method = sample.get("method", "grid")
    if method not in ("grid", "lhs", "sobol"):
        _fail(path, "[sample] method", f"{method!r} is not one of ['grid', 'lhs', 'sobol']")
    seed = data.get("seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        _fail(path, "seed", f"{seed!r} must be an integer")
    return motions, metrics, motion, sample, method, seed


def _vary(path, where: str, t: dict, bases: dict) -> Param:
    """One checked [[vary]] table."""
    for k in t:
        if k not in ("key", "values", "range", "unit"):
            _fail(path, f"{where} {k!r}", "unknown (allowed: key, values, range, unit)")
    key = t.get("key")
    if not isinstance(key, str):
        _fail(path, where, "needs key = 'brush.…' | 'material.…' | 'scene.…' | 'motion.…'")
    _check_key(path, where, key, bases)
    unit = key_unit(key)
    if "unit" in t and t["unit"] != unit:
        _fail(path, f"{where} {key}", f"unit = {t['unit']!r}, but the key is in {unit!r}")
    if ("values" in t) == ("range" in t):
        _fail(path, f"{where} {key}", "give either values = [...] or range = [lo, hi]")
    if "values" in t:
        vals = t["values"]
        if not isinstance(vals, list) or not vals:
            _fail(path, f"{where} {key}", "values is empty: list at least one value")
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
            _fail(path, f"{where} {key}", f"values = {vals!r} must be finite numbers ({unit})")
        return Param(key, tuple(float(v) for v in vals))
    r = t["range"]
    if not (isinstance(r, list) and len(r) == 2 and all(isinstance(v, (int, float)) for v in r)):
        _fail(path, f"{where} {key}", f"range = {r!r} must be [lo, hi] ({unit})")
    if not (math.isfinite(r[0]) and math.isfinite(r[1]) and r[0] < r[1]):
        _fail(path, f"{where} {key}", f"range = {r!r} is empty: need lo < hi ({unit})")
    return Param(key, (), float(r[0]), float(r[1]))


def _sample(path, method, sample, params, seed) -> np.ndarray:
    if method == "grid":
        for p in params:
            if not p.values:
                _fail(path, f"[[vary]] {p.key}", "method 'grid' needs values = [...], not a range")
        if "n" in sample:
            _fail(path, "[sample] n", "not used by method 'grid' (every combination runs)")
        grids = np.meshgrid(*[np.array(p.values) for p in params], indexing="ij")
        return np.stack([g.ravel() for g in grids], axis=1)
    n = sample.get("n")
    if not (isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 100_000):
        _fail(path, "[sample] n", f"{n!r} must be an integer in [1, 100000] (runs per motion)")
    for p in params:
        if p.lo is None:
            _fail(path, f"[[vary]] {p.key}", f"method {method!r} needs range = [lo, hi]")
    from scipy.stats import qmc

    d = len(params)
    if method == "lhs":
        u = qmc.LatinHypercube(d=d, seed=np.random.default_rng(seed)).random(n)
    else:
        if n & (n - 1):
            _fail(path, "[sample] n", f"{n} must be a power of 2 for method 'sobol' (balance)")
        u = qmc.Sobol(d=d, scramble=True, seed=np.random.default_rng(seed)).random(n)
    lo = np.array([p.lo for p in params])
    hi = np.array([p.hi for p in params])
    return lo + u * (hi - lo)


def base_tables(path, data) -> dict:
    """The dicts the keys point into: brush file, its material entry, scene file."""
    brush_path = resolve_config("brush", data.get("brush", "default"))
    brush = read_toml(brush_path)
    mfile = brush.get("materials_file")
    mpath = materials_path(brush_path.parent / mfile if mfile else None)
    materials = read_toml(mpath)
    mat = materials.get(brush.get("material", ""), {})
    try:
        spath = resolve_config("scene", data.get("scene", "flat_plate"))
    except ConfigError as e:
        _fail(path, "scene", str(e))
    return {
        "brush": brush,
        "material": mat,
        "scene": read_toml(spath),
        "motion": dict.fromkeys(MOTION_UNITS, 0.0),
        "_paths": {"brush": Path(brush_path), "materials": mpath, "scene": spath},
    }


def _check_key(path, where, key, bases):
    head, _, rest = key.partition(".")
    if head not in ("brush", "material", "scene", "motion") or not rest:
        _fail(path, f"{where} key {key!r}", "must start with brush., material., scene. or motion.")
    try:
        n = len(resolve(copy.deepcopy(bases[head]), rest, 0.0))
    except KeyError as e:
        _fail(path, f"{where} key {key!r}", f"unknown: {e.args[0]}")
    if n == 0:
        _fail(path, f"{where} key {key!r}", "matches nothing")


def resolve(d, dotted: str, value) -> list:
    """Set ``value`` at every place the dotted path (``*`` = every entry) names in ``d``; returns
    the places set (as paths).  Raises KeyError naming the first missing part."""
    parts = dotted.split(".")
    hits = []

    def walk(node, i, trail):
        part = parts[i]
        if isinstance(node, list):
            idx = (
                range(len(node))
                if part == "*"
                else [int(part)]
                if re.fullmatch(r"\d+", part)
                else None
            )
            if idx is None:
                raise KeyError(f"{'.'.join(trail) or '(top)'} is a list: use an index or *")
            items = [(k, node[k]) for k in idx]
        elif isinstance(node, dict):
            if part == "*":
                items = list(node.items())
            elif part in node:
                items = [(part, node[part])]
            else:
                raise KeyError(
                    f"{part!r} not in {'.'.join(trail) or '(top)'}{did_you_mean(part, list(node))}"
                )
        else:
            raise KeyError(f"{'.'.join(trail)} is a value, not a table")
        for k, child in items:
            if i == len(parts) - 1:
                if isinstance(child, (dict, list)):
                    raise KeyError(f"{'.'.join([*trail, str(k)])} is a table, not a number")
                node[k] = value
                hits.append(".".join([*trail, str(k)]))
            else:
                walk(child, i + 1, [*trail, str(k)])

    walk(d, 0, [])
    return hits
