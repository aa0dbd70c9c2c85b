"""``jaxheli report RESULT... [--diagnosis DIR_OR_JSON] [--data FILE[:t0-t1]]... [--all-flights] --out report.html``."""

from __future__ import annotations

import argparse

from ..report.build import write_report
from ._options import FLIGHT, FLIGHT_HELP, add_quiet_option


def add_report_parser(subparsers: argparse._SubParsersAction) -> argparse.ArgumentParser:
    """Register ``report`` on the ``jaxheli`` command line."""
    p = subparsers.add_parser(
        "report",
        help="one self-contained HTML report of identification results (tables, plots, gap diagnosis)",
        description="Compare one or several results of 'jaxheli identify' side by side in one HTML file with no "
        "external resources: data summary, parameters with 95 % intervals and standard errors, Table-1 metrics, "
        "time-domain verification, frequency responses with coherence, convergence curves and the gap diagnosis.",
    )
    p.add_argument("results", nargs="+", metavar="RESULT", help="result folder or result.json of jaxheli identify")
    p.add_argument("--diagnosis", default=None, metavar="DIR_OR_JSON",
                   help="folder or file of jaxheli diagnose (diagnosis.json) or jaxheli check (consistency.json)")
    p.add_argument("--data", action="append", default=[], metavar=FLIGHT,
                   help=f"a flight to plot (default: the training and validation files recorded in each result.json, "
                        f"when they exist): {FLIGHT_HELP}; several: repeat --data (one flight after each, as the "
                        "RESULTs are positional)")
    p.add_argument("--all-flights", action="store_true",
                   help="draw every model on every flight (default: each model on the flights it was fitted or "
                   "validated on; every model on a flight only --data names)")
    p.add_argument("--out", default="report.html", help="output HTML file (default report.html)")
    add_quiet_option(p)
    p.set_defaults(func=_cmd_report)
    return p


def _cmd_report(args: argparse.Namespace) -> int:
    path = write_report(args.results, args.out, diagnosis=args.diagnosis, data=args.data,
                        all_flights=args.all_flights)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return 0
