"""The `softproxy` command line: one subcommand per job, each with a `--json` form."""

from __future__ import annotations

import argparse
import json
import sys

from softproxy.fingertip import MODELS


def _print_table(rows: list[dict], columns: list[tuple[str, str, str]]) -> None:
    """Print `rows` as an aligned text table; `columns` are (key, header, format)."""
    cells = [[header for _, header, _ in columns]]
    for row in rows:
        cells.append(["-" if row.get(key) is None else format(row[key], fmt) for key, _, fmt in columns])
    widths = [max(len(r[i]) for r in cells) for i in range(len(columns))]
    for i, r in enumerate(cells):
        print("  ".join(c.rjust(w) if i and j else c.ljust(w) for j, (c, w) in enumerate(zip(r, widths))))


def cmd_models(args: argparse.Namespace) -> int:
    """List the fingertip models with their exponents and derived constants."""
    rows = [m.as_dict() for m in MODELS.values()]
    if args.json:
        print(json.dumps({"models": rows}, indent=2))
        return 0
    print("Fingertip models (seed 002, Table 1; torque limit M = mu' |P|^gamma)")
    _print_table(
        rows,
        [
            ("name", "model", "s"),
            ("gamma", "gamma", ".4f"),
            ("mu_prime_Nmm", "mu' (N·mm/N^g)", ".4f"),
            ("p_star_N", "P* (N)", ".4f"),
            ("torque_limit_at_1N_Nmm", "M@1N (N·mm)", ".3f"),
            ("torque_limit_at_3N_Nmm", "M@3N (N·mm)", ".3f"),
        ],
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="softproxy", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("models", help="list the fingertip models and their constants")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_models)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
