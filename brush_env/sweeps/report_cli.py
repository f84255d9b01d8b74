"""``brush-env sweep-report DIR`` (issue 16)."""

from __future__ import annotations


def add_arguments(parser) -> None:
    parser.description = "Effects and sensitivity of a sweep: DIR/report.md with figures."
    parser.add_argument("dir", help="a sweep's output directory (with results.csv)")


def run(args) -> int:
    from .report import sweep_report

    print(f"report: {sweep_report(args.dir)}")
    return 0
