"""``brush-env bench teeth``: the tooth row against the plate, and its SDF against the exact mesh.

Two tables (issue 13's acceptance):

1. **Speed**: the same press-and-scrub motion (``brush_env.experiments.tooth_row``: 2 mm press,
   hold, four 18 mm strokes at 20 mm/s) on ``flat_plate`` and on ``tooth_row`` (or a user mesh,
   ``--mesh``) at one fidelity level; wall time per simulated second (best of ``--repeats``),
   the ratio (tooth row / plate speed, the target is >= 50 %), Newton iterations per step (summed
   over the bristles; the machine-independent part of the cost), mean normal force and coverage.
   ``--ellipsoids`` adds two rows that tell curvature from the grid: the crowns replaced by four
   analytic ellipsoids of their size (``ELLIPSOID_ROW``), and the same ellipsoids as meshes baked
   into grids (trimesh's icosphere, 20,480 triangles, cell 0.15 mm).
2. **SDF error**: for each crown, the baked grid's distance and normal against the exact
   closest-triangle query at random points in the band and on the shell where a touching tip's
   centre sits (d = tip radius): max and RMS distance error, the rigorous bound sqrt(3) h, and the
   largest normal angle in the contact region next to the mesh's largest dihedral angle.

    brush-env bench teeth [--fidelity fast] [--repeats 2] [--json] [--quick] [--ellipsoids]
"""

from __future__ import annotations

import math
import time

import numpy as np

from .harness import emit, markdown_table, open_log


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "one stroke, one repeat (for tests)")
    p.add_argument("--repeats", type=int, default=2, help="runs per scene; the fastest counts")
    p.add_argument("--fidelity", default="fast", help="fidelity level of both scenes")
    p.add_argument("--mesh", default=None, help="a tooth mesh file in place of the crowns")
    p.add_argument("--mesh-units", default="mm", help="units of --mesh (mm, cm, m, um, in)")
    add_flag(
        p,
        "--ellipsoids",
        "also run the crowns as analytic ellipsoids and as those ellipsoids baked into grids",
    )


#: The crowns as axis-aligned ellipsoids of their size: (label, centre x [mm], semi-axis along the
#: row [mm]); all centred at y = 2.25, z = -4.5 mm with semi-axes 6.25 (y) and 4.5 (z) mm, so that
#: each spans its crown's box in y and z (``teeth.py``: y -4..8.5, crown tops at z = 0).
ELLIPSOID_ROW = (("PM1", -13.55, 3.5), ("PM2", -5.85, 3.5), ("M1", 3.35, 5.0), ("M2", 13.55, 4.5))


def ellipsoid_scenes(fidelity):
    """(analytic, baked): the tooth row with its crowns replaced by ``ELLIPSOID_ROW``, as analytic
    ellipsoids and as meshes baked into grids; the gum and the brush are the tooth row's."""
    from dataclasses import replace

    import trimesh

    from ..engine.fidelity import load_fidelity
    from ..engine.scene import Ellipsoid, MeshSurface
    from ..experiments.plan import resolve_scene

    base = resolve_scene(None, "tooth_row", load_fidelity(fidelity).bodies_per_bristle)
    gum = tuple(s for s in base.surfaces if s.label == "gum")
    ico = trimesh.creation.icosphere(subdivisions=5)
    ell, baked = [], []
    for lab, x, a in ELLIPSOID_ROW:
        centre, axes = (x, 2.25, -4.5), (a, 6.25, 4.5)
        ell.append(Ellipsoid(center=centre, semi_axes=axes, label=f"ellipsoid:{lab}"))
        V = np.asarray(ico.vertices) * np.asarray(axes) + np.asarray(centre)
        baked.append(MeshSurface(V, np.asarray(ico.faces), label=f"grid:{lab}"))
    return replace(base, surfaces=(*ell, *gum)), replace(base, surfaces=(*baked, *gum))


def _speed_rows(args, log) -> list[dict]:
    from ..engine.warmup import ensure_compiled
    from ..experiments.tooth_row import run_tooth_row

    ensure_compiled(notice=lambda m: print(m, file=log))
    strokes = 1 if args.quick else 4
    rows = []
    scenes = [("flat_plate", "flat_plate"), ("tooth_row", "tooth_row")]
    if args.ellipsoids:
        analytic, baked = ellipsoid_scenes(args.fidelity)
        scenes += [("ellipsoid_row", analytic), ("ellipsoid_row_baked", baked)]
    for label, scene in scenes:
        best = None
        for _ in range(1 if args.quick else max(1, args.repeats)):
            s = run_tooth_row(
                scene=scene,
                out_dir=f"/tmp/brush_env_bench_teeth_{label}",
                mesh=args.mesh if label == "tooth_row" else None,
                mesh_units=args.mesh_units,
                fidelity=args.fidelity,
                progress=False,
                plots=False,
                strokes=strokes,
            )
            if (
                best is None
                or s["performance"]["sim_wall_time_s"] < best["performance"]["sim_wall_time_s"]
            ):
                best = s
        perf, an = best["performance"], best["analysis"]
        rows.append(
            dict(
                scene=label,
                status=best["status"],
                fidelity=args.fidelity,
                simulated_s=perf["simulated_s"],
                wall_per_sim_s=perf["wall_per_sim_s"],
                newton_iterations_per_step=perf["newton_iterations_per_step"],
                mean_normal_force_N=an["strokes"]["normal_force_N"]["mean"],
                peak_gum_force_N=an["strokes"]["gum_force_N"]["peak"],
                coverage=an.get("coverage", {}).get("reachable"),
            )
        )
        print(f"  {label}: {perf['wall_per_sim_s']:.3f} s per simulated s", file=log)
    ratio = rows[0]["wall_per_sim_s"] / rows[1]["wall_per_sim_s"]
    for r in rows:
        r["speed_vs_plate"] = rows[0]["wall_per_sim_s"] / r["wall_per_sim_s"]
    print(f"  tooth row at {100 * ratio:.0f} % of the plate's speed", file=log)
    return rows


def _sdf_rows(args) -> list[dict]:
    import trimesh

    from ..engine import load_scene
    from ..engine.scene import MeshSurface, with_mesh

    scene = load_scene("tooth_row")
    if args.mesh:
        scene = with_mesh(scene, args.mesh, args.mesh_units)
    rng = np.random.default_rng(0)
    R = 0.44
    rows = []
    n = 1000 if args.quick else 20000
    for srf in scene.surfaces:
        if not isinstance(srf, MeshSurface):
            continue
        V, T = srf.vertices, srf.triangles
        c = V[T].mean(axis=1)
        nr = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
        nr /= np.linalg.norm(nr, axis=1)[:, None]
        pick = rng.integers(0, len(T), n)
        off = np.r_[rng.uniform(-0.8, 0.8, n // 2), rng.uniform(R - 0.05, R + 0.01, n - n // 2)]
        P = c[pick] + nr[pick] * off[:, None] + rng.normal(0, 0.05, (n, 3))
        t0 = time.perf_counter()
        d_ex, n_ex = srf.exact_query(P)
        t_ex = time.perf_counter() - t0
        grid = srf.sdf_grid()
        t0 = time.perf_counter()
        d_gr, n_gr = grid.query(P)
        t_gr = time.perf_counter() - t0
        err = np.abs(d_gr - d_ex)
        band = np.abs(d_ex) < 0.8
        shell = np.abs(d_ex - R) < 0.03
        region = (d_ex > -0.1) & (d_ex < 0.8)
        ang = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n_gr, n_ex), -1, 1)))
        m = trimesh.Trimesh(V, T, process=False)
        rows.append(
            dict(
                surface=srf.label,
                triangles=len(T),
                cell_mm=srf.cell,
                grid_MB=grid.distance.size * 16 / 1e6,
                band_max_err_mm=float(err[band].max()),
                bound_mm=math.sqrt(3) * srf.cell,
                shell_max_err_mm=float(err[shell].max()),
                shell_rms_err_mm=float(np.sqrt(np.mean(err[shell] ** 2))),
                max_normal_deg=float(ang[region].max()),
                mesh_max_dihedral_deg=float(np.degrees(m.face_adjacency_angles.max())),
                exact_us_per_query=1e6 * t_ex / n,
                grid_us_per_query=1e6 * t_gr / n,
            )
        )
    return rows


def bench_teeth(args) -> int:
    log = open_log(args)
    speed = [emit(args, dict(table="speed", **r)) for r in _speed_rows(args, log)]
    sdf = [emit(args, dict(table="sdf", **r)) for r in _sdf_rows(args)]
    if not args.json:
        print(
            markdown_table(
                speed,
                [
                    ("scene", lambda r: r["scene"]),
                    ("status", lambda r: r["status"]),
                    ("fidelity", lambda r: r["fidelity"]),
                    ("wall / sim s", lambda r: f"{r['wall_per_sim_s']:.3f}"),
                    ("speed vs plate", lambda r: f"{100 * r['speed_vs_plate']:.0f} %"),
                    ("Newton it / step", lambda r: f"{r['newton_iterations_per_step']:.1f}"),
                    ("mean Fn [N]", lambda r: f"{r['mean_normal_force_N']:.2f}"),
                    ("peak gum [N]", lambda r: f"{r['peak_gum_force_N']:.2f}"),
                    (
                        "coverage",
                        lambda r: "-" if r["coverage"] is None else f"{100 * r['coverage']:.1f} %",
                    ),
                ],
            )
        )
        print()
        print(
            markdown_table(
                sdf,
                [
                    ("surface", lambda r: r["surface"]),
                    ("triangles", lambda r: str(r["triangles"])),
                    ("cell [mm]", lambda r: f"{r['cell_mm']:g}"),
                    ("grid [MB]", lambda r: f"{r['grid_MB']:.1f}"),
                    ("band max err [um]", lambda r: f"{1e3 * r['band_max_err_mm']:.1f}"),
                    ("bound sqrt(3) h [um]", lambda r: f"{1e3 * r['bound_mm']:.0f}"),
                    (
                        "shell max / rms [um]",
                        lambda r: (
                            f"{1e3 * r['shell_max_err_mm']:.1f} / {1e3 * r['shell_rms_err_mm']:.2f}"
                        ),
                    ),
                    ("normal max [deg]", lambda r: f"{r['max_normal_deg']:.1f}"),
                    ("mesh dihedral max [deg]", lambda r: f"{r['mesh_max_dihedral_deg']:.1f}"),
                    (
                        "exact / grid [us/query]",
                        lambda r: f"{r['exact_us_per_query']:.2f} / {r['grid_us_per_query']:.2f}",
                    ),
                ],
            )
        )
    return 0 if all(r["status"] == "ok" for r in speed) else 1
