"""``brush-env bench steps``: one scene's press-and-scrub motion (or the paper turn on the plate),
stepped, for A/B comparisons by Newton iterations and by instruction counts.

Wall time drifts by up to 30 % on a shared VM; the Newton iterations are deterministic and the
instructions retired by the step loop drift by < 0.1 %.  The motion is ``bench teeth``'s (2 mm
press, hold, ``--strokes`` 18 mm strokes at 20 mm/s) on ``--scene`` at ``--fidelity``; it prints
the steps, the Newton iterations summed over the bristles and the wall time of the loop.  With
``--motion turn`` it is the paper turn of ``bench element`` on the plate instead (1 ms steps), the
motion on which buckled tips touch their neighbours and the coupled tip-tip solve works.

``--callgrind`` switches valgrind callgrind's instrumentation on just before the loop and off after
it (``callgrind_control -i on|off``), so that callgrind's "Collected" total is the loop alone
(numba's first call runs before it)::

    valgrind --tool=callgrind --collect-atstart=yes --instr-atstart=no \\
        brush-env bench steps --scene tooth_row --strokes 1 --callgrind

numba compiles for the CPU it sees, and valgrind's virtual CPU is not the host's, so a cache
compiled natively would be compiled again under valgrind (hours).  Set ``NUMBA_CPU_NAME`` and
``NUMBA_CPU_FEATURES`` to what valgrind reports, both for a native warm-up run and for the
valgrind runs (docs/benchmarks.md, "Instruction counts").
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import time

import numpy as np

from .harness import emit, markdown_table, open_log


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object on stdout (machine info on stderr)")
    add_flag(p, "--callgrind", "toggle callgrind's instrumentation around the step loop")
    p.add_argument(
        "--window",
        type=int,
        nargs=2,
        default=None,
        metavar=("START", "COUNT"),
        help="measure only COUNT steps from step START (the motion before runs unmeasured)",
    )
    p.add_argument(
        "--symbols",
        default=None,
        help="write {address: kernel} of the compiled engine kernels here (bench cost's map)",
    )
    p.add_argument(
        "--motion",
        choices=("scrub", "turn"),
        default="scrub",
        help="scrub: the press and strokes on --scene (4 ms steps); turn: the paper turn on the "
        "flat_plate scene (bench element's: 3 mm press in 0.5 s, 0.25 s hold, one 20 mm circle; "
        "1 ms steps to t = 7.233 s), where buckled tips touch and the coupled solve works",
    )
    p.add_argument("--scene", default="tooth_row", help="scene name or file (default tooth_row)")
    p.add_argument("--fidelity", default="fast", help="fidelity level (default fast)")
    p.add_argument("--strokes", type=int, default=1, help="18 mm strokes after the press (1-8)")
    p.add_argument(
        "--bodies", type=int, default=None, help="bodies per bristle (default: the level's)"
    )
    p.add_argument(
        "--sweeps",
        type=int,
        default=None,
        help="tip-tip sweeps per step, 1 = one sweep, more = coupled (default: the level's)",
    )


def _toggle(on: bool) -> None:
    subprocess.run(
        ["callgrind_control", "-i", "on" if on else "off", str(os.getpid())],
        check=True,
        stdout=subprocess.DEVNULL,
    )


def _turn(sim, scene):
    """The paper turn's trajectory (bench element's motion, ``bench.contact.CONTACT_GRID_FULL``):
    tips touching the plate at t = 0, 3 mm press, hold, one turn of the 20 mm circle."""
    from ..experiments.plan import plate_height
    from ..motion import R0
    from .contact import CONTACT_GRID_FULL as G
    from .contact import press_and_circle

    traj, _ = press_and_circle(sim.touch_height(R0, plate_height(scene)), G["press"], G["hold"])
    return traj


def bench_steps(args) -> int:
    from ..engine import Simulator
    from ..engine.fidelity import level_settings
    from ..experiments.plan import resolve_scene
    from ..experiments.tooth_row import DEFAULTS, scrub_motion
    from ..user_errors import UserError

    if not 1 <= args.strokes <= 8:
        raise UserError(f"--strokes = {args.strokes}: must be in [1, 8]")
    log = open_log(args)
    turn = args.motion == "turn"
    # the scrub: run_tooth_row's step (the level's max_substep splits it); the turn: bench
    # element's 1 ms
    dt = 1e-3 if turn else DEFAULTS["dt"]
    over = {}
    if args.bodies is not None:
        over["bodies_per_bristle"] = args.bodies
    if args.sweeps is not None:
        over["tip_tip_sweeps"] = args.sweeps
    settings = dataclasses.replace(level_settings(args.fidelity, dt=dt), **over)
    scene = resolve_scene(None, "flat_plate" if turn else args.scene, None)
    sim = Simulator(scene, settings)
    if turn:
        traj = _turn(sim, scene)
        ts = np.arange(int(round(traj.duration / dt)) + 1) * dt
    else:
        traj, _ = scrub_motion(sim, {**DEFAULTS, "strokes": args.strokes})
        ts = np.arange(int(traj.duration / dt)) * dt
    P, R, _, _ = traj.sample(ts)
    sim.reset(P[0], R[0])
    sim.step(P[1], R[1])  # numba's first call, outside the measurement
    first, last = 2, len(ts)
    if args.window is not None:
        first, count = args.window
        if not 2 <= first < len(ts) or not 1 <= count <= len(ts) - first:
            raise UserError(
                f"--window {first} {count}: the motion has steps 2..{len(ts) - 1} "
                f"(start >= 2, count >= 1, start + count <= {len(ts)})"
            )
        last = first + count
        for k in range(2, first):  # the motion up to the window, unmeasured
            sim.step(P[k], R[k])
    iterations = 0
    if args.callgrind:
        _toggle(True)
    t0 = time.perf_counter()
    for k in range(first, last):
        iterations += sim.step(P[k], R[k]).iterations
    wall = time.perf_counter() - t0
    if args.callgrind:
        _toggle(False)
    if args.symbols:
        import json

        from .cost import kernel_symbols

        with open(args.symbols, "w") as fh:
            json.dump(kernel_symbols(), fh)
    row = emit(
        args,
        dict(
            scene="flat_plate" if turn else str(args.scene),
            motion=args.motion,
            fidelity=args.fidelity,
            bristles=sim.model.n_bristles,
            bodies=settings.bodies_per_bristle,
            sweeps=settings.tip_tip_sweeps,
            strokes=args.strokes,
            steps=last - first,
            first_step=first,
            newton_iterations=iterations,
            wall_s=wall,
        ),
    )
    if not args.json:
        print(
            markdown_table(
                [row],
                [
                    ("scene", lambda r: r["scene"]),
                    ("fidelity", lambda r: r["fidelity"]),
                    ("bodies", lambda r: str(r["bodies"])),
                    ("sweeps", lambda r: str(r["sweeps"])),
                    ("strokes", lambda r: str(r["strokes"])),
                    ("steps", lambda r: str(r["steps"])),
                    ("Newton iterations", lambda r: str(r["newton_iterations"])),
                    ("wall [s]", lambda r: f"{r['wall_s']:.2f}"),
                ],
            ),
            file=log,
        )
    return 0
