"""The reduced model's joints (``prb.py``) for one bristle: lengths and spring constants.

A bristle of length L [mm], Young's modulus E [MPa], second moments I_y, I_z [mm^4] becomes a
rigid stub g0 L, two links g1 L, g2 L (g0 + g1 + g2 = 1) and two joints with springs

    k_a,i = c_i E I_y / L  (bending toward the thin side, local z),
    k_b,i = c_i E I_z / L  (toward the wide side, local y)          [N mm / rad],

and joint damping c = beta k with beta = max(2 zeta, 1) / omega_1 [s] (the full chain's
stiffness-proportional damping, eq 4-5, or the first mode's time scale standing in for the
inertia the model leaves out, whichever is longer).

and the springs' torque is k (e + c3 e^3): toward the thin side c3 one per joint (the rod's
change of stiffness at large turns), toward the wide side one c3w for both joints (2026-11-27:
the wide side pressed and dragged with its tip stuck softens far more than the thin side, where
the full chain twists and lays over; the two-joint chain with a linear wide-side spring kept +18
% of normal force at 0.4 L of travel, ``calibration`` "Drag targets").

The dimensionless constants (g0, g1, c1, c2, c31, c32) are fitted to the continuum: the planar
geometrically exact rod with shear and extension (``validation.rod``, what the full chain converges
to with many bodies), pressed onto a plate with a sliding and with a sticking tip
(``brush-env calibrate``, ``prb_fit.py``).  A fit depends on the bristle's slenderness (shear),
Poisson ratio and lean, so it is made per bristle type and cached by the content of that type
(as the baked SDF grids are); :data:`DEFAULT` are the constants of the default brush's inner
bristle, used until a type has its own fit.
"""

from __future__ import annotations

import math

from .beam import first_bending_omega

#: (g0, g1, c1, c2, c31, c32): stub and first link as fractions of L, joint spring
#: coefficients, the two joints' cubic stiffening [1/rad^2]
DEFAULT = (0.07, 0.32, 4.2, 2.9, -0.13, -0.13)


#: the twist spring k_t = twist G J / L [N mm/rad] (G J the section's torsion stiffness, the
#: full chain's eq 1-3); ``twist`` is fitted per type with the drag targets
#: (``calibration.fit``) and stored as the eighth constant.  This is the fit's start and the
#: value of ``DEFAULT``: set by hand (2026-11-26) against the full chain (12 mid-element bodies)
#: dragging each default type, pressed L / 4, toward its wide side (``bench drag``): 1 gave
#: -25 % / -52 % (inner / outer sliding normal force), 4 -9 % / -6 %, 6.5 -1.5 % / -0.2 %, 8 +37 %
#: (the inner strip no longer turns its bend over).  The full chain twists mostly in its root
#: third (0.15 of its 0.22 rad within 3 of 12 bodies) and shares the turn between twist and
#: bending along its length, where the joint turns both links rigidly
TWIST = 6.5


def joint_parameters(br, lean: float) -> tuple:
    """(s0, l1, l2 [mm], k_a1, k_b1, k_a2, k_b2, k_t [N mm/rad], beta [s], the cubics of a1, b1,
    a2, b2 (c31, c3w, c32, c3w) [1/rad^2],
    the five rest angles [rad], ``rest_angles``) of ``br`` (``BristleConfig``) on a brush of
    effective lean ``lean`` [rad], with its type's fitted constants (``constants_for``)."""
    g0, g1, c1, c2, c31, c32, sz, twist, cw = constants_for(br, lean)
    L = br.length
    E = br.material.E
    sec = br.section
    Iy, Iz = sec.I_y, sec.I_z
    # the joints' damping time: the material's stiffness-proportional damping (2 zeta / omega_1,
    # as the full chain's elements), but at least one period of the first bending mode over
    # 2 pi: the model has no inertia, and this relaxation stands for it -- a snap (a tip torn
    # off its stiction, a bristle springing back) takes about that long in the full chain too,
    # and the implicit step stays well posed through it
    omega1 = first_bending_omega(E, min(Iy, Iz), br.material.density, sec.area, L)
    beta = max(2.0 * br.material.damping_ratio, 1.0) / omega1
    l1, l2 = g1 * L, (1.0 - g0 - g1) * L
    return (
        g0 * L,
        l1,
        l2,
        c1 * E * Iy / L,
        sz * c1 * E * Iz / L,
        c2 * E * Iy / L,
        sz * c2 * E * Iz / L,
        twist * br.material.G * sec.J / L,
        beta,
        c31,
        cw,
        c32,
        cw,
        *rest_angles(l1, l2, lean),
    )


#: [rad] the rest bend of the two joints along the fold that keeps the tip in place (see
#: ``rest_angles``)
REST_BEND = 0.02


def rest_angles(l1: float, l2: float, lean: float) -> tuple:
    """The joints' rest angles (a1, b1, a2, b2, t) [rad]: a bend of REST_BEND at joint 1 and the
    turn at joint 2 that keeps the tip on the bristle's axis (to first order; it shortens by
    ~0.01 mm), toward the side the full chain and the rod buckle to (the elbow away from the lean:
    ``prb_kernels._bow_side``).  Why: a two-link chain pressed slowly from straight takes the
    branch its own kinematics prefer, which for a leaning bristle is the other side; the small
    rest bend makes it take the continuum's (tests/engine/test_prb.py presses one against the
    full chain).  No lean: no bend (a straight bristle picks its side when it buckles)."""
    if lean == 0.0:
        return (0.0, 0.0, 0.0, 0.0, 0.0)
    e = math.copysign(REST_BEND, lean)
    return (e, 0.0, -e * (l1 + l2) / l2, 0.0, 0.0)


# --------------------------------------------------------------------------- the cache
import hashlib  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

#: the calibrations that ship with the package (the brushes of configs/brushes)
SHIPPED = Path(__file__).resolve().parent / "prb_calibrations.json"
#: bump when the reduced model or the fit changes: older records are not used
VERSION = 13

_override: tuple | None = None
_memory: dict = {}
_warned: set = set()


def user_cache() -> Path:
    """The user's calibration file: $BRUSH_ENV_CACHE/prb_calibrations.json or
    ~/.cache/brush_env/prb_calibrations.json."""
    root = os.environ.get("BRUSH_ENV_CACHE") or os.path.join(
        os.path.expanduser("~"), ".cache", "brush_env"
    )
    return Path(root) / "prb_calibrations.json"


def bristle_key(br, lean: float) -> str:
    """Content key of a bristle type: what the fit depends on (section, length, material's E
    and nu, tip radius, the brush's effective lean [rad]) and the model's VERSION."""
    sec, mat = br.section, br.material
    text = json.dumps(
        [
            VERSION,
            sec.kind,
            round(sec.width, 9),
            round(sec.thickness, 9),
            round(br.length, 9),
            round(mat.E, 9),
            round(mat.nu, 9),
            round(br.tip_radius, 9),
            round(abs(lean), 12),
        ]
    )
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def bristle_types(brush) -> dict:
    """key -> (a bristle of that type, the brush's effective lean [rad]) for every distinct
    bristle type of ``brush`` (``BrushConfig``)."""
    lean = float(brush.effective_lean)
    out: dict = {}
    for br in brush.bristles:
        out.setdefault(bristle_key(br, lean), (br, lean))
    return out


def _read(path: Path) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def lookup(key: str) -> dict | None:
    """The calibration record of a bristle type (shipped, then the user's), or None."""
    if key in _memory:
        return _memory[key]
    for path in (SHIPPED, user_cache()):
        rec = _read(path).get(key)
        if rec is not None:
            _memory[key] = rec
            return rec
    return None


def _write(path: Path, data: dict) -> None:
    """The calibration file ``path`` <- ``data``, through a temporary file (atomic)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)


def store(key: str, rec: dict, ship: bool = False) -> None:
    """Add a record to the shipped file (``ship``) or the user's cache (written atomically)."""
    path = SHIPPED if ship else user_cache()
    data = _read(path)
    data[key] = rec
    _write(path, data)
    _memory[key] = rec


def prune(keep: set, path: Path = SHIPPED) -> int:
    """Drop from the calibration file ``path`` (the shipped one by default) every record whose
    key is not in ``keep`` -- an older VERSION's, or a type no brush uses any more: ``store``
    adds new records beside the old, whose keys nothing looks up again.  Returns how many."""
    data = _read(path)
    kept = {k: v for k, v in data.items() if k in keep}
    _write(path, kept)
    return len(data) - len(kept)


def set_override(constants) -> None:
    """Use ``constants`` (g0, g1, c1, c2, c31, c32, wide-side scale, twist, wide-side cubic;
    without the last two: TWIST and 0) for every bristle built until reset with None (the fit
    evaluates candidates this way)."""
    global _override
    if constants is None:
        _override = None
        return
    c = tuple(float(v) for v in constants)
    _override = c + (TWIST, 0.0)[len(c) - 7 :] if len(c) < 9 else c


def constants_for(br, lean: float) -> tuple:
    """The fitted constants of the bristle type (the override during a fit); a type never
    calibrated gets :data:`DEFAULT` with a warning naming the command that fits it."""
    if _override is not None:
        return _override
    key = bristle_key(br, lean)
    rec = lookup(key)
    if rec is not None:
        return tuple(rec["constants"])
    if key not in _warned:
        _warned.add(key)
        warnings.warn(
            f"the reduced bristle model has no calibration for a {br.section.kind} "
            f"{br.section.width:g} x {br.section.thickness:g} mm bristle, {br.length:g} mm, "
            f"E = {br.material.E:g} MPa, lean {math.degrees(lean):.3g} deg: using the default "
            "brush's constants (forces may be off by tens of %); `brush-env calibrate BRUSH` "
            "fits it (the envs and experiments do it on first use)",
            RuntimeWarning,
            stacklevel=3,
        )
    return DEFAULT + (1.0, TWIST, 0.0)
