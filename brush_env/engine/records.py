"""Named records of the kernels' data: what the numba kernels take instead of long argument lists.

Two kinds of record, both read by field name (never by a column constant, issue 27):

- ``collections.namedtuple`` (numba-native: passed to and built inside nopython code, no
  allocation): the argument bundles below and ``StepParams`` (the integrator's settings, typed
  scalars: integers as integers, the static flag as a bool);
- numpy structured dtypes for per-body / per-tip / per-surface tables (``BODY``, ``TIP_ARGS``,
  ``TIP_STATE``, ``CONTACT_LAW``, ``SURFACE``): numba reads ``bp[i].half``, ``st.delta[a]``,
  ``srf.kind`` at the same byte offsets the float64 columns they replaced had, so the kernels'
  loads and stores are unchanged; Python reads ``ts["fn"]``.  Integers (a surface's kind and
  grid, the tip's deepest surface and sliding flag) are int64.

Arrays in a record are views owned by the Python side (``Simulator``); the kernels write into
them in place.

==================  ========================================================================
record              fields [unit]
==================  ========================================================================
``ModelArrays``     bstart (nb+1,) body ranges; bp (N,) body parameters (``BODY``);
                    K (N, 6, 6) element stiffness (eq 1-3); root_p (nb, 3) [mm], root_R (nb, 3, 3)
                    root pose in the TCP frame; elem (N,) element formulation of each body's
                    element (``ELEM_*``)
``Chain``           pos, rot, vel, omg: body poses [mm] and rates [mm/s, rad/s] at t_n; ppos,
                    prot, pvel, pomg at t_{n-1}; pppos, pprot at t_{n-2} (all bodies)
``Drive``           hist_ok (nb,) whole steps of history; tcp_p (4, 3) [mm], tcp_R (4, 3, 3): TCP
                    at t_{n-1}, t_n, t_{n+1}, t_{n-2} (rows 0-3)
``ContactScene``    surf (ns,) surfaces (``SURFACE``); cp (1,) contact laws (Tables 2-3,
                    ``CONTACT_LAW``); tips (nb, 7) every tip's node, velocity and radius;
                    pair_ptr, pair_idx tip-tip pairs (CSR); mesh (the scene's triangle mesh);
                    tip_args (nb,) and tip_state (nb,) per tip (``TIP_ARGS``, ``TIP_STATE``);
                    sdf (hdr, vals) the scene's baked SDF grids (sdf.py)
``NewtonCache``     per-bristle factored Newton matrices kept across steps: D, G, L (N, 6, 6),
                    piv (N, 6), key (nb,) the c0/h they were built for, age (nb,) steps,
                    S (nb, 6, 6) the tip body's Schur complement without the tip load; E (N, 6)
                    each element's strain at its last (sub)step's start and EK (N, 24) the
                    poses it came from: body i's in EK[i, 0:12], the base node's in
                    EK[b0, 12:24] (``predict._strain_history``: e_{n-1} of the next step)
``StepOut``         per bristle: rootw (nb, 6) [N, N mm] root element's load on the head; iters,
                    nsub, status (nb,)
``Bristle``         b (index), b0 (first body), n (bodies), il (tip body)
``Substep``         one (sub)step: two-step formula c0, c1, c2 (c1 = c2 = 0 for statics); h [s],
                    inv_h [1/s]; static; g (3,) gravity [mm/s^2]; Newton rtol, maxit and the
                    factors' largest age jage [steps]
``Base``            base (root node) poses: start pAs/RAs, end pAe/RAe, t_{n-1} pAp/RAp, t_{n-2}
                    pAq/RAq of the (sub)step
``Node``            one element end: c (3,) body centre [mm], R (3, 3), half (body half length)
``Trial``           a Newton correction to search along: capped step alpha, slope g0 = dq . r,
                    residual norm nrm at its start, whole (True: a direction uphill of the
                    merit may be taken whole, the solve's first such), fresh (the factors were
                    rebuilt for it: a failed search ends the solve without a residual)
``Attempt``         how ``newton_solve`` starts and ends one (sub)step: extrap (the predictor's
                    order, or WARM) and split (True: a converged step whose tip dived into a
                    surface is refused, to be halved: ``newton._met_within``)
``Damp``            element rate terms: ehist (6,), gs, hs (see ``_kernels.element_force``)
``History``         constants of a (sub)step (``predict._prepare``): cm, vm, Lm, thp (n, 3),
                    Rn (n, 3, 3), ehist (n, 6), gs, hs (n,); and thn (n, 3), each body's
                    rotation vector log(R Rn^T) at the last residual evaluation (its angular
                    rate, ``residual._inertia_residual``; what ``newton._commit`` takes)
``Sweeps``          the Gauss-Seidel sweeps' start state, warm starts and partner tips
``Work``            the scratch of ``step_bristles`` (allocated once per Simulator)
``StepParams``      the integrator's settings: h, method, static, rtol, maxit, maxlev, g, jage,
                    sweeps, tttol (see the class comment)
==================  ========================================================================
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

#: largest group of touching bristles the tip-tip coupling solves as one dense system
MAX_GROUP = 256

#: why a compiled rollout (``prb_rollout``, ``chain_rollout``) stopped before its last step, and
#: the names ``Simulator.rollout`` / ``follow`` report
STOP_NONE = 0
STOP_DIVERGENCE = 1
STOP_FORCE = 2
STOP_HEAD = 3
STOP_PENETRATION = 4
STOP_REASONS = {
    STOP_NONE: None,
    STOP_DIVERGENCE: "divergence",
    STOP_FORCE: "force_limit",
    STOP_HEAD: "head_contact",
    STOP_PENETRATION: "penetration",
}

# --- structured records: numpy dtypes read by field name in the kernels (``bp[i].half``,
# ``st.delta[a]``).  Each keeps the byte layout of the float64 columns it replaced, so a kernel's
# loads and stores are the ones it had; integers are int64 (8 bytes, as the float they replace).

#: one body's parameters, ``ModelArrays.bp`` (N,): mass [t]; J principal inertia Jx, Jy, Jz
#: [t mm^2]; half body length, centre to node [mm]; element length l [mm]; stiffness-proportional
#: damping beta [s]; fscale: the bristle's force scale E I / L^2 [N] (Newton tolerance)
BODY = np.dtype(
    [
        ("mass", "f8"),
        ("J", "f8", 3),
        ("half", "f8"),
        ("length", "f8"),
        ("beta", "f8"),
        ("fscale", "f8"),
    ]
)

#: a tip's arguments, ``ContactScene.tip_args`` (nb,): external dead force fext [N, world];
#: tip sphere radius [mm]; cax: the bristle's axial compliance L / (E A) [mm/N] behind its tip,
#: in series with the contact laws (0 for the full chain, whose elements carry it; the reduced
#: chain's rigid links do not: ``contact.series_law``); axis: the unit direction it acts along
#: [world] (the reduced chain's chord at the step's start)
TIP_ARGS = np.dtype([("fext", "f8", 3), ("radius", "f8"), ("cax", "f8"), ("axis", "f8", 3)])

#: a tip's contact state, ``ContactScene.tip_state`` (nb,) (contact.py writes it):
#: delta: stiction deformation Delta [mm, world] (committed); hist: (c0 + c1) p_n + c2 p_{n-1} of
#: the tip node (rate history, v = (c0 (p - pn) + hist) / h) [mm]; pn: tip node at the step start
#: [mm]; fn: normal force of the last
#: evaluation [N]; ft: tangential (friction) force [N, world]; slide: 1 if sliding (|v| > v_s);
#: pen: penetration [mm]; cpt: contact point [mm]; dnew: trial stiction deformation of the last
#: evaluation; ftt: tip-tip normal force magnitude (sum) [N]; beta: beta of the step start
#: (committed), see ``contact.tip_load``; bnew: beta at the slip speed of the last evaluation;
#: surf: index of the deepest surface the tip touched at the last evaluation (-1: none)
TIP_STATE = np.dtype(
    [
        ("delta", "f8", 3),
        ("hist", "f8", 3),
        ("pn", "f8", 3),
        ("fn", "f8"),
        ("ft", "f8", 3),
        ("slide", "i8"),
        ("pen", "f8"),
        ("cpt", "f8", 3),
        ("dnew", "f8", 3),
        ("ftt", "f8"),
        ("beta", "f8"),
        ("bnew", "f8"),
        ("surf", "i8"),
    ]
)

#: one body's shaft contact, ``ContactScene.shaft`` (N,) (shaft.py writes it; empty when the
#: scene's ``shaft_contact`` is off): the body's capsule (static): radius [mm] (half the section's
#: smaller side), lo, hi: its axis from lo to hi along the body's x from the centre [mm] (the tip
#: body's stops a tip radius short of the tip node; hi <= lo: no capsule); near: the broad phase
#: lets it reach a surface this step (1) or not (0); committed stiction state delta [mm, world]
#: and beta (eq 7-10, as ``TIP_STATE``); of the last evaluation: dnew, bnew, pn (the contact's
#: material point at the step start [mm]), ft friction [N, world], slide, fn normal force (sum
#: over surfaces) [N], pen deepest penetration of the contact sphere [mm] (< 0: clearance; -1e30:
#: not evaluated), cpt contact point on the surface [mm], nrm its normal, surf its index (-1:
#: none), u the contact sphere's centre along the axis [mm from the body centre]
SHAFT = np.dtype(
    [
        ("radius", "f8"),
        ("lo", "f8"),
        ("hi", "f8"),
        ("near", "i8"),
        ("delta", "f8", 3),
        ("beta", "f8"),
        ("dnew", "f8", 3),
        ("bnew", "f8"),
        ("pn", "f8", 3),
        ("ft", "f8", 3),
        ("slide", "i8"),
        ("fn", "f8"),
        ("pen", "f8"),
        ("cpt", "f8", 3),
        ("nrm", "f8", 3),
        ("surf", "i8"),
        ("u", "f8"),
    ]
)

#: the contact laws, ``ContactScene.cp`` (1,): the fields of ``scene.ContactParams`` (Tables 2-3):
#: tip-surface normal law k, m1, c, m2, m3 (eq 6); friction mu_s, mu_d, v_s, v_d, delta_max
#: (eq 7-10); tip-tip normal law k_tt, m1_tt, c_tt, m2_tt, m3_tt (Table 3)
CONTACT_LAW = np.dtype(
    [
        (name, "f8")
        for name in (
            "k",
            "m1",
            "c",
            "m2",
            "m3",
            "mu_s",
            "mu_d",
            "v_s",
            "v_d",
            "delta_max",
            "k_tt",
            "m1_tt",
            "c_tt",
            "m2_tt",
            "m3_tt",
        )
    ]
)

# kinds of surface (``SURFACE.kind``)
SURF_PLANE = 0  # a: a point, b: the unit outward normal
SURF_CYLINDER = 1  # outside of an infinite cylinder: a: point on the axis, b: axis dir, radius
SURF_MESH = 2  # the scene's triangle mesh (``ContactScene.mesh``); radius: search radius [mm]
SURF_SPHERE = 3  # sdf.sphere_gap: a: centre, radius
SURF_CAPSULE = 4  # sdf.capsule_gap: a: end a, b: end b, radius
SURF_ELLIPSOID = 5  # sdf.ellipsoid_gap: a: centre, b: semi-axes
SURF_GRID = 6  # a baked SDF grid (``ContactScene.sdf``); grid: its index
SURF_KINDS = ("plane", "cylinder", "mesh", "sphere", "capsule", "ellipsoid", "grid")

#: a surface, ``ContactScene.surf`` (ns,): kind (SURF_*), two points/vectors a, b [mm], a radius
#: [mm] and an SDF grid's index.  sdf.py's kernels read a surface as its float64 row
#: (``surface_floats``: kind's slot, a, b, radius at 0, 1-3, 4-6, 7)
SURFACE = np.dtype(
    [("kind", "i8"), ("a", "f8", 3), ("b", "f8", 3), ("radius", "f8"), ("grid", "i8")]
)
#: float64 slots of one SURFACE record
SURF_FLOATS = SURFACE.itemsize // 8


def surface_row(kind: int, a=(0.0, 0.0, 0.0), b=(0.0, 0.0, 0.0), radius=0.0, grid=0):
    """One SURFACE record (a 0-d structured array)."""
    row = np.zeros((), SURFACE)
    row["kind"] = kind
    row["a"] = a
    row["b"] = b
    row["radius"] = radius
    row["grid"] = grid
    return row


def surface_floats(surf) -> np.ndarray:
    """SURFACE records (ns,) or one (0-d) as the float64 rows (ns, SURF_FLOATS) sdf.py reads."""
    surf = np.ascontiguousarray(np.atleast_1d(surf))
    return surf.view(np.float64).reshape(-1, SURF_FLOATS)


#: the integrator's settings (``DFMChain._make_prm``): time step h [s]; method METHOD_EULER or
#: METHOD_BDF2; static equilibrium (no inertia, no damping); Newton tolerance rtol on the residual
#: relative to the bristle force scale; Newton iterations per attempt maxit; sub-stepping levels
#: maxlev (h / 2**maxlev is the smallest step); gravity g (3,) [mm/s^2]; steps a factored Newton
#: matrix may be reused jage; most Gauss-Seidel sweeps over the bristles per step (1: one sweep,
#: the tip-tip lag); tttol [mm]: a partner tip that moved by less than this does not call for
#: another sweep
StepParams = namedtuple(
    "StepParams",
    ["h", "method", "static", "rtol", "maxit", "maxlev", "g", "jage", "sweeps", "tttol"],
)
METHOD_EULER = 0
METHOD_BDF2 = 1

ModelArrays = namedtuple("ModelArrays", ["bstart", "bp", "K", "root_p", "root_R", "elem"])
Chain = namedtuple(
    "Chain", ["pos", "rot", "vel", "omg", "ppos", "prot", "pvel", "pomg", "pppos", "pprot"]
)
Drive = namedtuple("Drive", ["hist_ok", "tcp_p", "tcp_R"])
ContactScene = namedtuple(
    "ContactScene",
    [
        "surf",
        "cp",
        "tips",
        "pair_ptr",
        "pair_idx",
        "mesh",
        "tip_args",
        "tip_state",
        "sdf",
        "shaft",
    ],
)
NewtonCache = namedtuple("NewtonCache", ["D", "G", "L", "piv", "key", "age", "S", "E", "EK"])
StepOut = namedtuple("StepOut", ["rootw", "iters", "nsub", "status"])
Bristle = namedtuple("Bristle", ["b", "b0", "n", "il"])
Substep = namedtuple(
    "Substep", ["c0", "c1", "c2", "h", "inv_h", "static", "g", "rtol", "maxit", "jage"]
)
Base = namedtuple("Base", ["pAs", "RAs", "pAe", "RAe", "pAp", "RAp", "pAq", "RAq"])
Node = namedtuple("Node", ["c", "R", "half"])
Trial = namedtuple("Trial", ["alpha", "g0", "nrm", "whole", "fresh"])
Attempt = namedtuple("Attempt", ["extrap", "split"])
Damp = namedtuple("Damp", ["ehist", "gs", "hs"])
History = namedtuple("History", ["cm", "vm", "Lm", "thp", "Rn", "ehist", "gs", "hs", "thn"])

#: scratch of the element kernels (strain, generalised forces, finite-difference perturbations)
ElementScratch = namedtuple(
    "ElementScratch", ["e", "out12", "base12", "pert12", "cP", "RP", "th", "pt"]
)
#: scratch of the tip load (eq 6-10, Table 3) and the penetration limit
#: vt: tip velocity; nrm, cpt: the contact normal and point; vs, dn: slip velocity and stiction
#: deformation in the tangent plane; ft: friction force; pnrm, pcpt: normal and contact point of
#: one surface in a loop over surfaces; gd: grad of a gap; J (3, 3): a surface's dn/dpt [1/mm];
#: A (3, 3): d(sum_s Fn_s n_s)/dpt [N/mm]; gres (3,) = -d|R|/dpt [N/mm], R = sum_s Fn_s n_s:
#: friction's Newton coupling to the normal forces of several surfaces; res (3,) that R [N]
#: (several or curved surfaces only: what the reduced model's friction presses against)
TipScratch = namedtuple(
    "TipScratch",
    ["vt", "nrm", "cpt", "vs", "dn", "ft", "pnrm", "pcpt", "gd", "J", "A", "gres", "res"],
)
#: scratch of the shaft contact (shaft.py): D6 (nmax, 6, 6) each body's block of the Newton
#: matrix from its shaft contacts, on (nmax,) 1 where a body's block is set; F (3,), K (3, 3) one
#: contact's force and tangent; J, gd a surface's normal rate; pt, pp, v (3,) points, velocity
ShaftScratch = namedtuple("ShaftScratch", ["D6", "on", "F", "K", "J", "gd", "pt", "pp", "v"])
#: what the shaft's contact kernels take of the workspace (``shaft.shaft_load``): the scratch
#: they use and the start-of-step poses (s_pos, s_rot of ``Iterate``)
ShaftWork = namedtuple("ShaftWork", ["sh", "tipw", "blk", "s_pos", "s_rot"])
#: scratch of the tip block of the Newton matrix (3x3 products)
BlockScratch = namedtuple("BlockScratch", ["Sr", "SF", "KS", "SrK", "SrKS", "SFSr"])
#: scratch of the predictors and the chain update
MotionScratch = namedtuple(
    "MotionScratch",
    [
        "Tr",
        "phi1",
        "phi2",
        "pAo",
        "pBo",
        "dpA",
        "dpB",
        "pAn",
        "dd",
        "tmp",
    ],
)
#: one bristle's iterate and its saved copies: residual, correction, start and trial states
Iterate = namedtuple(
    "Iterate",
    [
        "U",
        "res",
        "r0",
        "dq",
        "s_pos",
        "s_rot",
        "s_vel",
        "s_omg",
        "t_pos",
        "t_rot",
        "tipF",
        "tipK",
        "tip",
        "dtip",
    ],
)
#: a bristle's state at the start of the step (restored when every sub-step level fails)
Backup = namedtuple("Backup", ["v3", "R", "tip_state", "shaft"])
#: the sweeps of ``step_bristles`` and the tip-tip coupling (``coupling.py``): every bristle's
#: state at the step's start (v3, R, tip_state, hist_ok as in ``Backup``, all bodies), the last
#: sweep's solution (warm_pos, warm_rot), the partner tips each bristle was solved against (used,
#: per CSR pair entry), count = [sweeps run, re-solves, 0 settled / 1 unsettled / 2 fell back]
#: of the last step; per bristle the tip load of its solution tipF (nb, 3) [N], tipK (nb, 3, 3)
#: [N/mm], its tip node and velocity before it was placed xs (nb, 6) and where the first sweep
#: holds it tips0 (nb, 6); groups (parent, grouped, slot, members); the dense system A, x, piv
#: (3 rows per bristle of a group); scratch: one tip node's stiffness H (3, 3) [N/mm], A6, piv6,
#: W3, Fc, Kc, f, C, e6; shaft (the bodies' shaft states at the step's start); lead (nb,): the
#: fraction of its extrapolated move each tip is moved on for the first sweep, ext (nb, 6): that
#: move [mm] and the change of its velocity [mm/s] (``sweeps.lead_partners``); near: the step's
#: near lists of partners (``NearPairs``)
Sweeps = namedtuple(
    "Sweeps",
    [
        "v3",
        "R",
        "tip_state",
        "hist_ok",
        "warm_pos",
        "warm_rot",
        "used",
        "count",
        "tipF",
        "tipK",
        "H",
        "xs",
        "tips0",
        "parent",
        "grouped",
        "slot",
        "members",
        "A",
        "x",
        "piv",
        "A6",
        "piv6",
        "W3",
        "Fc",
        "Kc",
        "f",
        "C",
        "e6",
        "shaft",
        "lead",
        "ext",
        "near",
    ],
)
#: the step's near lists of tip-tip partners (``near.py``): ptr (nb + 1), q and idx (entries of
#: the pair list and the partners, CSR over the bristles), d (2,) = [D: how far [mm] a held tip
#: is from its anchor this step (inf: no near list), M: the margin [mm] (< 0: lists off)], anc
#: (nb, 3): every tip where the lists were last built, its anchor [mm] (NaN: never built)
NearPairs = namedtuple("NearPairs", ["ptr", "q", "idx", "d", "anc"])
Work = namedtuple(
    "Work", ["it", "hist", "base", "tp", "tR", "el", "tipw", "blk", "mot", "backup", "sw", "sh"]
)


def make_work(
    nmax: int,
    n_bodies: int = 1,
    n_bristles: int = 1,
    n_pair_entries: int = 0,
    near_margin: float = -1.0,
) -> Work:
    """Scratch arrays for ``step_bristles`` (allocated once per Simulator; nmax = most bodies per
    bristle; n_bodies, n_bristles, n_pair_entries: the whole brush, for the sweeps; near_margin
    [mm]: the near lists' margin, ``near.NEAR_MARGIN``; < 0: every partner loop takes the whole
    list)."""

    def v(*shape):
        return np.zeros(shape)

    it = Iterate(
        v(nmax, 6, 6),
        v(nmax, 6),
        v(nmax, 6),
        v(nmax, 6),
        v(nmax, 3),
        v(nmax, 3, 3),
        v(nmax, 3),
        v(nmax, 3),
        v(nmax, 3),
        v(nmax, 3, 3),
        v(3),
        v(3, 3),
        v(3),
        v(3),
    )
    hist = History(
        v(nmax, 3),
        v(nmax, 3),
        v(nmax, 3),
        v(nmax, 3),
        v(nmax, 3, 3),
        v(nmax, 6),
        v(nmax),
        v(nmax),
        v(nmax, 3),
    )
    base = Base(v(3), v(3, 3), v(3), v(3, 3), v(3), v(3, 3), v(3), v(3, 3))
    el = ElementScratch(v(6), v(12), v(12), v(12), v(3), v(3, 3), v(3), v(3))
    tipw = TipScratch(*(v(3, 3) if f in ("J", "A") else v(3) for f in TipScratch._fields))
    blk = BlockScratch(*(v(3, 3) for _ in BlockScratch._fields))
    mot = MotionScratch(*(v(3, 3) if f == "Tr" else v(3) for f in MotionScratch._fields))
    backup = Backup(v(7, nmax, 3), v(3, nmax, 3, 3), np.zeros(1, TIP_STATE), np.zeros(nmax, SHAFT))
    # the coupling's dense system: only with tip-tip pairs, at most MAX_GROUP bristles
    n3 = 3 * min(n_bristles, MAX_GROUP) if n_pair_entries else 1
    sw = Sweeps(
        v(7, n_bodies, 3),
        v(3, n_bodies, 3, 3),
        np.zeros(n_bristles, TIP_STATE),
        np.zeros(n_bristles, np.int64),
        v(n_bodies, 3),
        v(n_bodies, 3, 3),
        v(max(n_pair_entries, 1), 3),
        np.zeros(3, np.int64),
        v(n_bristles, 3),
        v(n_bristles, 3, 3),
        v(3, 3),
        v(n_bristles, 6),
        v(n_bristles, 6),
        *(np.zeros(n_bristles, np.int64) for _ in range(4)),
        v(n3, n3),
        v(n3),
        np.zeros(n3, np.int64),
        v(6, 6),
        np.zeros(6, np.int64),
        v(3, 3),
        v(3),
        v(3, 3),
        v(3),
        v(3, 3),
        v(6),
        np.zeros(n_bodies, SHAFT),
        v(n_bristles),
        v(n_bristles, 6),
        NearPairs(
            np.zeros(n_bristles + 1, np.int64),
            np.zeros(max(n_pair_entries, 1), np.int64),
            np.zeros(max(n_pair_entries, 1), np.int64),
            np.array([np.inf, near_margin]),
            np.full((n_bristles, 3), np.nan),
        ),
    )
    sh = ShaftScratch(
        v(nmax, 6, 6),
        np.zeros(nmax, np.int64),
        *(v(3, 3) if f in ("K", "J") else v(3) for f in ShaftScratch._fields[2:]),
    )
    return Work(it, hist, base, v(3), v(3, 3), el, tipw, blk, mot, backup, sw, sh)


def make_newton_cache(n_bodies: int, n_bristles: int) -> NewtonCache:
    """Empty per-bristle Newton factors (every key 0: built at the first step)."""
    return NewtonCache(
        np.zeros((n_bodies, 6, 6)),
        np.zeros((n_bodies, 6, 6)),
        np.zeros((n_bodies, 6, 6)),
        np.zeros((n_bodies, 6), np.int64),
        np.zeros(n_bristles),
        np.zeros(n_bristles, np.int64),
        np.zeros((n_bristles, 6, 6)),
        np.zeros((n_bodies, 6)),
        np.full((n_bodies, 24), np.nan),  # no key matches NaN: nothing cached yet
    )
