"""``brush-env bench TARGET``: speed-versus-error benchmarks, one module per target.

``engine`` (free brush under a moving TCP, vs a converged reference), ``contact`` (the plate press
+ one circle turn), ``convergence`` (self-convergence of the contact run in dt and bodies),
``element`` (both beam elements against the converged turn), ``press`` (the 3 mm press's hold
force at every step size), ``branch`` (hold direction and jamming angles over step sizes),
``random`` (the env under random actions), ``env`` (Gymnasium env steps per second), ``teeth``
(tooth row vs plate speed, SDF vs exact mesh), ``steps`` (one scene's scrub motion: Newton
iterations, instructions under callgrind), ``drag`` (a pressed brush dragged toward the
bristles' wide and thin sides), ``touchdown`` (one bristle landing while dragged, the
reduced models against the converged chain), ``episodes`` (how far env episodes run and why
they end), ``cost`` (one bristle-step split into its parts by callgrind instruction counts),
``coupled`` (the coupled tip-tip solve's cost and error on the paper turn), ``compile`` (the
first-start numba compile, in a fresh cache).  Each target has its own options
(``brush-env bench engine --help``); a new target is a module with ``bench_<name>(args)`` (and
``add_arguments(p)`` for its options) and an entry in :data:`TARGETS`.
"""

from __future__ import annotations

import argparse

from ..user_errors import add_flag
from . import (
    branch,
    compile,
    contact,
    convergence,
    cost,
    coupled,
    drag,
    element,
    engine,
    env,
    episodes,
    fidelity,
    planar,
    press,
    steps,
    teeth,
    touchdown,
)

#: name -> (run function, its options (None: the common ones), one-line help)
TARGETS = {
    "engine": (
        engine.bench_engine,
        None,
        "free brush under a moving TCP: error vs a converged "
        "reference and speed, over bodies x dt x integrator",
    ),
    "contact": (
        contact.bench_contact,
        None,
        "3 mm press + one turn of the circle on the plate: error "
        "and speed over bodies x dt x integrator x tip-tip",
    ),
    "convergence": (
        convergence.bench_convergence,
        None,
        "self-convergence of the contact run in time step and in bodies per bristle",
    ),
    "element": (
        element.bench_element,
        element.add_arguments,
        "flat-plate turn against its converged reference (mid element, 24 bodies, 0.125 ms) "
        "for both beam elements",
    ),
    "press": (
        press.bench_press,
        press.add_arguments,
        "3 mm press: hold force at every step size (0.5-50 ms), with and without the internal "
        "split of SimSettings.max_substep, against the 0.125 ms run",
    ),
    "drag": (
        drag.bench_drag,
        drag.add_arguments,
        "a pressed bristle and the pressed brush dragged toward the wide and the thin side: "
        "normal and lateral force at each level against the converged chain",
    ),
    "touchdown": (
        touchdown.bench_touchdown,
        touchdown.add_arguments,
        "one bristle landing on the plate while its root is dragged (the reference circle's "
        "touch-down): onset, peak and dragged normal force of reduced and fast against the "
        "converged chain",
    ),
    "branch": (
        branch.bench_branch,
        branch.add_arguments,
        "reference experiment (two turns) over dt x integrator x bodies x lean: hold force "
        "direction and jamming angles against the 0.25 ms run",
    ),
    "random": (
        env.bench_random_target,
        env.add_random_arguments,
        "FlatPlate-v0 under uniform random actions at several solver-step limits: divergences, "
        "tip-force spikes and penetration against the smallest limit",
    ),
    "env": (
        env.bench_env_target,
        env.add_arguments,
        "Gymnasium env steps per second, single and vectorised",
    ),
    "fidelity": (
        fidelity.bench_fidelity,
        fidelity.add_arguments,
        "every fidelity level (configs/fidelity) against reference: the paper's turn and "
        "random-policy env episodes, error and speed, Pareto plot",
    ),
    "teeth": (
        teeth.bench_teeth,
        teeth.add_arguments,
        "tooth row against the plate (same press-and-scrub motion and fidelity: speed ratio) "
        "and the crowns' SDF grids against the exact mesh query (error, normals)",
    ),
    "steps": (
        steps.bench_steps,
        steps.add_arguments,
        "one scene's press-and-scrub motion (bench teeth's): steps, Newton iterations, wall; "
        "--callgrind counts the step loop's instructions under valgrind",
    ),
    "cost": (
        cost.bench_cost,
        cost.add_arguments,
        "one bristle-step of the full chain split into Jacobian, factorisation, solve, contact, "
        "residual, coupling by callgrind instruction counts, beside each part's arithmetic",
    ),
    "coupled": (
        coupled.bench_coupled,
        coupled.add_arguments,
        "the paper turn at one sweep and coupled against the same bodies at 0.125 ms: CPU, "
        "Newton iterations, sweeps, RMS error, phase means and stick-slip event times",
    ),
    "planar": (
        planar.bench_planar,
        planar.add_arguments,
        "pymunk planar bristle row against the 3-D engine on the same stroke: force and tip "
        "errors per phase, speed, pymunk's largest stable step, overlay plot",
    ),
    "episodes": (
        episodes.bench_episodes,
        episodes.add_arguments,
        "ToothRow-v0 under its scrub reference and FlatPlate-v0 under random actions at one "
        "fidelity: how many env steps each episode runs and why it ends",
    ),
    "compile": (
        compile.bench_compile,
        compile.add_arguments,
        "first-start numba compile of every kernel set (empty cache) and the cached start: "
        "wall, CPU, retired instructions",
    ),
}


def _common(p: argparse.ArgumentParser, cold_start: bool = True) -> None:
    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "reduced grid (for tests)")
    p.add_argument(
        "--repeats",
        type=int,
        default=3,
        help="runs per row; the fastest wall time is reported (default 3)",
    )
    if cold_start:
        add_flag(p, "--no-cold-start", "skip the cold-start measurement (fresh numba compile)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """One sub-parser per target, each with its own options and help."""
    sub = parser.add_subparsers(
        dest="target", required=True, metavar="TARGET", parser_class=type(parser)
    )
    for name, (_, options, helptext) in TARGETS.items():
        p = sub.add_parser(name, help=helptext, description=helptext)
        (options or _common)(p)


def run(args) -> int:
    """Run the chosen target; its exit code."""
    return TARGETS[args.target][0](args)
