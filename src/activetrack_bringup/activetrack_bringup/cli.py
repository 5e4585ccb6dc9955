"""The ``activetrack`` command line."""

from __future__ import annotations

import argparse
import sys


def _cmd_smoke(args: argparse.Namespace) -> int:
    from activetrack_bringup.smoke import run_smoke

    result = run_smoke(timeout=args.timeout)
    print(f"{'message':<20} {'consumer':<14} {'fields intact':<14} consumed")
    for name, consumer, intact, consumed in result.rows:
        print(f"{name:<20} {consumer:<14} {intact!s:<14} {consumed}")
    print(f"smoke: {'OK' if result.ok else 'FAILED'} in {result.wall_time_s:.2f} s")
    return 0 if result.ok else 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="activetrack", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    smoke = sub.add_parser(
        "smoke", help="bring up sim, tracker and planner and exchange every message type"
    )
    smoke.add_argument("--timeout", type=float, default=10.0, help="seconds (default 10)")
    smoke.set_defaults(func=_cmd_smoke)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
