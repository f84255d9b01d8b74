"""``brush-env validate``: the discrete beam model against closed-form references.

* ``validate cantilever --alpha A --bodies N``: dead tip load P = A E I / L^2 perpendicular to the
  axis, static solve.  Bending about the thin direction (load along local z, I = I_y = b h^3/12)
  unless ``--plane wide``.  Reference: linear Timoshenko (with shear) for A <= 0.1, the exact
  elastica (inextensible, unshearable) above.
* ``validate frequency --bodies N``: first bending frequency against Euler-Bernoulli.
* ``validate buckling --tip free|pinned --bodies N --compression D [D ...] --lean-deg A
  --element mid|paper``: one bristle pressed onto a plate, the plate force and the tip's shift
  against the planar geometrically exact rod (and the elastica).
* ``validate all``: the acceptance suite (table, non-zero exit on any failure).
"""

from __future__ import annotations

import json
from dataclasses import asdict

from ..engine.settings import ELEMENTS
from ..user_errors import add_flag
from .buckling import COMPRESSIONS, TIPS, BucklingCase, buckling
from .suite import PAPER_INNER, Geometry, cantilever, format_table, frequency, suite


def _geometry_args(p, plane: bool = True) -> None:
    g = PAPER_INNER
    p.add_argument("--bodies", type=int, default=6, help="rigid bodies per bristle (default 6)")
    p.add_argument("--length", type=float, default=g.length, help="L [mm] (default %(default)s)")
    p.add_argument("--width", type=float, default=g.width, help="b [mm] (default %(default)s)")
    p.add_argument(
        "--thickness", type=float, default=g.thickness, help="h [mm] (default %(default)s)"
    )
    p.add_argument("--E", type=float, default=g.E, help="Young's modulus [MPa] (default 7)")
    p.add_argument("--nu", type=float, default=g.nu, help="Poisson ratio (default 0.48)")
    p.add_argument(
        "--element",
        choices=sorted(ELEMENTS),
        default="paper",
        help="beam element formulation (default %(default)s)",
    )
    if plane:
        p.add_argument(
            "--plane",
            choices=("thin", "wide"),
            default="thin",
            help="bending about the thin (load along h) or wide direction",
        )
    add_flag(p, "--json", "print JSON")


def add_arguments(parser) -> None:
    """One sub-parser per case, each with its geometry options."""
    sub = parser.add_subparsers(
        dest="case", required=True, metavar="CASE", parser_class=type(parser)
    )
    p = sub.add_parser("cantilever", help="static tip load, against Timoshenko / elastica")
    p.add_argument("--alpha", type=float, required=True, help="load P L^2 / (E I) [-]")
    p.add_argument(
        "--increments",
        type=int,
        default=None,
        help="load steps of the static solve (default ceil(alpha))",
    )
    _geometry_args(p)
    p = sub.add_parser("frequency", help="first bending frequency, against Euler-Bernoulli")
    _geometry_args(p)
    p = sub.add_parser(
        "buckling", help="one bristle pressed onto a plate, against the geometrically exact rod"
    )
    p.add_argument("--tip", choices=TIPS, default="free", help="free (mu = 0) or pinned (sticking)")
    p.add_argument(
        "--compression",
        type=float,
        nargs="+",
        default=list(COMPRESSIONS),
        help="clamp descent after touch minus tip penetration [mm], ascending "
        "(default %(default)s)",
    )
    p.add_argument(
        "--lean-deg", type=float, default=1.0, help="lean from the plate normal [deg] (default 1)"
    )
    p.add_argument(
        "--radius", type=float, default=0.44, help="tip sphere radius [mm] (default 0.44)"
    )
    _geometry_args(p, plane=False)
    p.set_defaults(element="mid")
    p = sub.add_parser("all", help="the acceptance suite; exit 1 on any failure")
    add_flag(p, "--json", "print JSON")


def run(args) -> int:
    """Run the chosen case and print it (table or JSON); exit 1 if the suite fails."""
    if args.case == "all":
        rows = suite()
        ok = all(r.passed for r in rows)
        if args.json:
            print(
                json.dumps(
                    {"passed": ok, "checks": [{**asdict(r), "passed": r.passed} for r in rows]},
                    indent=1,
                )
            )
        else:
            print(format_table(rows))
            print(f"\n{sum(r.passed for r in rows)}/{len(rows)} checks passed")
        return 0 if ok else 1
    geom = Geometry(args.length, args.width, args.thickness, args.E, args.nu)
    if args.case == "cantilever":
        res = cantilever(args.alpha, args.bodies, geom, args.increments, args.plane, args.element)
        _report(res, args.json, lambda: _cantilever_lines(res, geom, args))
    elif args.case == "buckling":
        case = BucklingCase(
            length=args.length,
            width=args.width,
            thickness=args.thickness,
            E=args.E,
            nu=args.nu,
            radius=args.radius,
            lean_deg=args.lean_deg,
            tip=args.tip,
            bodies=args.bodies,
            element=args.element,
        )
        res = buckling(case, args.compression)
        _report(res, args.json, lambda: _buckling_lines(res, geom, args))
    else:
        res = frequency(args.bodies, geom, args.plane, args.element)
        _report(res, args.json, lambda: _frequency_lines(res, geom, args))
    return 0


def _report(res: dict, as_json: bool, lines) -> None:
    """Print one case's result: as JSON, or as the text lines ``lines()`` gives."""
    if as_json:
        print(json.dumps(res, indent=1))
    else:
        for line in lines():
            print(line)


def _cantilever_lines(res: dict, geom: Geometry, args) -> list[str]:
    head = (
        f"cantilever {geom.label(args.bodies)} alpha={args.alpha:g} {args.plane}; "
        f"reference: {res['reference_kind']} ({res['reference_note']})"
    )
    return [head] + [
        f"  {k:14s} computed {res['computed'][k]:.8g}  reference "
        f"{res['reference'][k]:.8g}  rel. error {res['rel_error'][k]:+.3e}"
        for k in res["computed"]
    ]


def _frequency_lines(res: dict, geom: Geometry, args) -> list[str]:
    return [
        f"first bending frequency {geom.label(args.bodies)} {args.plane}: computed "
        f"{res['computed_hz']:.6g} Hz, Euler-Bernoulli {res['reference_hz']:.6g} Hz, "
        f"rel. error {res['rel_error']:+.3e}"
    ]


def _buckling_lines(res: dict, geom: Geometry, args) -> list[str]:
    head = (
        f"buckling {geom.label(args.bodies)} {args.element} element, {args.tip} tip, lean "
        f"{args.lean_deg:g} deg; reference: {res['reference_kind']} ({res['reference_note']})"
    )
    rows = [head, "  compression [mm]  force [N]  rod [N]  elastica [N]  rel. error  shift [mm]"]
    c, r, e = res["computed"], res["reference"], res["elastica"]
    for j, d in enumerate(res["settings"]["compression_mm"]):
        rows.append(
            f"  {d:16.4f}  {c['force_N'][j]:9.6f}  {r['force_N'][j]:.6f}"
            f"  {e['force_N'][j]:12.6f}  {res['rel_error']['force_N'][j]:+10.3e}"
            f"  {c['tip_shift_mm'][j]:9.4f}"
        )
    return rows
