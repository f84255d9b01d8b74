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
    add_flag(parser, "--no-progress", "no progress bar")


def run(args) -> int:
    from .sweep import run_sweep

    info = run_sweep(
        args.spec,
        args.out,
        workers=args.workers,
        ray_address=args.ray_address,
        progress=not args.no_progress,
    )
    print(
        f"{info['runs']} runs: {info['done_before']} already done, {info['ran']} run now "
        f"({info['failed']} failed in all) in {info['wall_s']:.0f} s on {info['executor']}; "
        f"table {info['table']}"
    )
    return 0 if info["failed"] == 0 else 1
