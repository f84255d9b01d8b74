"""``brush-env sweep`` and ``brush-env sweep-report`` (issue 16)."""

from __future__ import annotations

from ..user_errors import add_flag


def add_arguments(parser) -> None:
    parser.description = (
        "Run a design sweep: every run of SPEC (configs/sweeps/*.toml or a path) with the "
        "reference experiment; one row per run in OUT/results.csv, each run's summary.json "
        "under OUT/runs/; finished runs are skipped when rerun (resume). One sweep per OUT at "
        "a time (OUT/.lock): a second one exits with code 2 naming the holder's PID."
    )
    parser.add_argument("spec", help="sweep spec: a TOML path or a name in configs/sweeps")
    parser.add_argument("--out", required=True, help="output directory (resumed if it exists)")
    parser.add_argument(
        "--workers", type=int, default=None, help="local worker processes (default: all cores)"
    )
    parser.add_argument(
        "--ray-address",
        default=None,
        metavar="ADDR",
        help="run on Ray: auto (a running cluster), HOST:PORT, or local (a fresh local "
        "instance); needs the [cluster] extra",
    )
    parser.add_argument(
        "--limit",
        type=int,
        default=None,
        metavar="N",
        help="run only the spec's first N variants (a small budget first); a later run without "
        "--limit resumes into the full sweep and does not redo them",
    )
    add_flag(
        parser,
        "--dry-run",
        "list the variants (done or to do) and the estimated time from the runs already "
        "measured in --out; run nothing, write nothing",
    )
    add_flag(parser, "--no-progress", "no progress bar")


def _check_counts(args) -> None:
    """--limit and --workers in the flags' own terms, before the spec is even read."""
    from ..engine.checks import ConfigError

    for flag, value, unit in (
        ("--limit", args.limit, "variants"),
        ("--workers", args.workers, "processes"),
    ):
        if value is not None and value < 1:
            raise ConfigError(f"{flag} = {value} is out of range: must be >= 1 ({unit})")


def run(args) -> int:
    from .sweep import run_sweep

    _check_counts(args)
    if args.dry_run:
        return dry_run(args)
    info = run_sweep(
        args.spec,
        args.out,
        workers=args.workers,
        ray_address=args.ray_address,
        progress=not args.no_progress,
        limit=args.limit,
    )
    rest = info["runs"] - info["done_before"] - info["ran"]
    more = f"; {rest} more without --limit" if args.limit is not None and rest > 0 else ""
    print(
        f"{info['runs']} runs: {info['done_before']} already done, {info['ran']} run now "
        f"({info['failed']} failed in all) in {info['wall_s']:.0f} s on {info['executor']}; "
        f"table {info['table']}{more}"
    )
    return 0 if info["failed"] == 0 else 1


def dry_run(args) -> int:
    """``--dry-run``: one line per variant, then what is left and how long it should take."""
    from .sweep import plan_sweep

    plan = plan_sweep(args.spec, args.out, workers=args.workers, limit=args.limit)
    keys = list(plan["units"])
    head = ["id", "motion", *(f"{k} [{plan['units'][k]}]" for k in keys), "status"]
    rows = [
        [r["id"], r["motion"], *(f"{r['params'][k]:.4g}" for k in keys)]
        + ["done" if r["done"] else "to run"]
        for r in plan["runs"]
    ]
    widths = [max(len(str(x)) for x in col) for col in zip(head, *rows)]
    for row in (head, *rows):
        print("  ".join(str(x).ljust(w) for x, w in zip(row, widths)).rstrip())
    n, todo = len(plan["runs"]), plan["todo"]
    line = f"{n} variants ({plan['spec']}), {n - todo} done in {args.out}, {todo} to run"
    if plan["measured_s"] is None:
        line += "; no run measured yet in --out: `--limit 1` runs the first and measures it"
    else:
        line += (
            f"; estimated {_minutes(plan['estimate_s'])}: {plan['waves']} wave(s) of "
            f"{plan['workers']} worker(s) x {plan['measured_s']:.0f} s, the median run time of "
            f"{plan['n_measured']} run(s) measured in --out"
        )
    print(line)
    return 0


def _minutes(s: float) -> str:
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.0f} min"
