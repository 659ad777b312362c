"""``workbench rcwa solve|table|info``: one solve, an efficiency table, what a table holds (rcwa, rcwa.table)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING

import rcwa
from workbench.catalog import format_table_info, table_info
from workbench.commands.arguments import (
    STRUCTURE_HELP,
    RegistryNames,
    add_registry_option,
    angle_range_argument,
    count_argument,
    orders_argument,
)
from workbench.core.executor import DaskExecutor
from workbench.report_text import solve_table

if TYPE_CHECKING:  # rcwa.table pulls in scipy and shapely: imported where a table is built
    from rcwa.table import BuildReport, TableSettings

FACTORIZATION_HELP = ("Fourier factorization rule: auto = li for 1D and for 2D cells of rectangles only, nv for other "
                      "2D cells; li = Li's inverse rule (Li 1996 in 1D, 1997 in 2D); nv = the normal vector method; "
                      "laurent = the plain product rule, for comparison")
PRESET_HELP = ("paper: 31 wavelengths 400-700 nm, 2 deg steps in theta and phi, 61 (1D) or 11x11 (2D) harmonics "
               "(the CD takes about 70-95 s here); draft: 11 wavelengths, 5/10 deg steps, 31 or 7x7 harmonics "
               "(seconds); fine: 81 wavelengths 380-780 nm, 1 deg steps, 81 or 15x15 harmonics")


def factorization_rules() -> Iterable[str]:
    from rcwa.factorization import FACTORIZATION_RULES  # deferred: pulls in scipy and shapely (start-up time)

    return FACTORIZATION_RULES


def stack_methods() -> Iterable[str]:
    from rcwa.solver import STACK_METHODS  # deferred: as factorization_rules

    return STACK_METHODS


FACTORIZATION_CHOICES = RegistryNames(factorization_rules)
STACK_CHOICES = RegistryNames(stack_methods)


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add the ``rcwa`` group: ``solve``, ``table`` and ``info``."""
    parser = commands.add_parser("rcwa", help="rigorous coupled-wave analysis")
    actions = parser.add_subparsers(dest="rcwa_command", required=True)
    _add_solve(actions)
    _add_table(actions)
    _add_info(actions)


def _add_solve(actions: argparse._SubParsersAction) -> None:
    solve = actions.add_parser("solve", help="diffraction efficiencies for one incident plane wave")
    solve.add_argument("structure", help=STRUCTURE_HELP)
    solve.add_argument("--wavelength", type=float, required=True, metavar="NM", help="vacuum wavelength in nm")
    solve.add_argument("--theta", type=float, default=0.0, metavar="DEG", help="polar angle of incidence (default 0)")
    solve.add_argument("--phi", type=float, default=0.0, metavar="DEG", help="azimuth of incidence from +x (default 0)")
    solve.add_argument("--orders", type=orders_argument, required=True, metavar="N|NX,NY",
                       help="retained harmonics per direction (odd)")
    solve.add_argument("--pol", choices=["s", "p", "unpolarized"], default="unpolarized",
                       help="incident polarization; unpolarized is the mean of s and p")
    add_registry_option(solve, "--factorization", FACTORIZATION_CHOICES, default="auto", help=FACTORIZATION_HELP)
    add_registry_option(solve, "--stack", STACK_CHOICES, default="etm",
                        help="layer stacking: enhanced transmittance matrix (default) or Redheffer star product")
    solve.add_argument("--json", action="store_true",
                       help="print one JSON object instead of a table (with each order's Jones and Mueller matrices)")


def _add_table(actions: argparse._SubParsersAction) -> None:
    table = actions.add_parser("table", help="efficiency table over wavelength x incidence angles (for rendering)")
    table.add_argument("structure", help=STRUCTURE_HELP)
    table.add_argument("--out", required=True, metavar="PATH", help="table directory (zarr); resumed if unfinished")
    table.add_argument("--preset", choices=["paper", "draft", "fine"], default="paper", help=PRESET_HELP)
    table.add_argument("--theta-step", type=float, metavar="DEG", help="polar-angle step (default: the preset's)")
    table.add_argument("--phi-step", type=float, metavar="DEG", help="azimuth step (default: the preset's)")
    table.add_argument("--wavelengths", metavar="START:STOP:COUNT",
                       help="nm, inclusive (e.g. 400:700:31), or NM,NM,... (default: the preset's)")
    table.add_argument("--theta-range", type=angle_range_argument, metavar="LO,HI",
                       help="polar angles to cover (deg; default: 0,90)")
    table.add_argument("--phi-range", type=angle_range_argument, metavar="LO,HI",
                       help="azimuths to cover (deg, in the stored range; default: all of it)")
    table.add_argument("--orders", type=orders_argument, metavar="N|NX,NY",
                       help="retained harmonics (odd; default: the preset's for the structure's dimension)")
    table.add_argument("--keep-orders", type=orders_argument, metavar="N|NX,NY",
                       help="orders stored (odd, <= --orders; default: the preset's, at most --orders)")
    table.add_argument("--pol", choices=["unpolarized", "s", "p", "all"], default="unpolarized",
                       help="polarizations stored; all = s, p and their mean")
    table.add_argument("--reflection-only", action="store_true", help="store R only, even where the substrate transmits")
    table.add_argument("--both-sides", action="store_true", help="also light from below (see-through elements)")
    add_registry_option(table, "--factorization", FACTORIZATION_CHOICES, default="auto", help=FACTORIZATION_HELP)
    table.add_argument("--no-symmetry", action="store_true", help="compute the whole azimuth range")
    table.add_argument("--threads", type=count_argument(1), default=None, help="solver threads (default: all cores)")
    table.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the chunks on this dask.distributed scheduler (default: threads in this process)")
    table.add_argument("--workers", type=count_argument(1), metavar="N",
                       help="start a local dask cluster with N worker processes (default: none, threads in this process)")
    table.add_argument("--force", action="store_true", help="overwrite a different table at --out")
    table.add_argument("--quiet", action="store_true", help="no progress bar")


def _add_info(actions: argparse._SubParsersAction) -> None:
    info = actions.add_parser("info", help="what a table holds: grid, settings, size, symmetry, integrity")
    info.add_argument("table", metavar="TABLE", help="a table folder written by `workbench rcwa table`")
    info.add_argument("--json", action="store_true", help="print one JSON object instead of text")


def run(args: argparse.Namespace) -> int:
    return ACTIONS[args.rcwa_command](args)


def run_solve(args: argparse.Namespace) -> int:
    structure = rcwa.load_structure(args.structure)
    result = rcwa.solve(structure, args.wavelength, args.theta, args.phi, args.orders, args.pol, args.factorization,
                        args.stack)
    print(json.dumps(solve_record(result), indent=2) if args.json else solve_table(result))
    return 0


def solve_record(result) -> dict:
    """``rcwa solve --json``: the result, each order with its Jones and Mueller matrices
    (rcwa.polarimetry; null for a side where the order does not propagate, and for pol s or p,
    whose other column is not solved)."""
    from rcwa.polarimetry import POLARIMETRY_CONVENTION, order_polarimetry

    record = result.to_dict()
    record["polarimetry"] = POLARIMETRY_CONVENTION
    for entry, order in zip(record["orders"], result.orders, strict=True):
        entry.update(order_polarimetry(order))
    return record


def run_table(args: argparse.Namespace) -> int:
    from rcwa.table import build_table, settings_for  # deferred: pulls in scipy and shapely (start-up time)

    structure = rcwa.load_structure(args.structure)
    settings = settings_for(
        structure, args.preset, theta_step=args.theta_step, phi_step=args.phi_step, wavelengths=args.wavelengths,
        orders=args.orders, keep=args.keep_orders, pol=args.pol, reflection_only=args.reflection_only,
        both_sides=args.both_sides, factorization=args.factorization, use_symmetry=not args.no_symmetry,
        theta_range=args.theta_range, phi_range=args.phi_range,
    )
    if args.scheduler or args.workers:
        with DaskExecutor(args.scheduler, args.workers) as executor:
            report = build_table(structure, settings, args.out, progress=not args.quiet, force=args.force, executor=executor)
    else:
        report = build_table(structure, settings, args.out, threads=args.threads, progress=not args.quiet, force=args.force)
    if report.cached:
        print(f"{args.out}: up to date (request {report.key[:12]}), served from the cache in {report.seconds * 1e3:.1f} ms")
        return 0
    print(_table_summary(args.out, structure.name, settings, report))
    from rcwa.table import format_summary, read_table_metadata, truncation_summary  # deferred: as above

    print("\n".join(format_summary(truncation_summary(read_table_metadata(args.out)))[:3]))  # the largest differences
    return 0


def _table_summary(out: str, name: str, settings: TableSettings, report: BuildReport) -> str:
    points = len(settings.wavelengths_nm) * len(settings.theta_deg) * len(settings.phi_deg)
    lines = [f"{out}: {name}, {len(settings.wavelengths_nm)} wavelengths x {len(settings.theta_deg)} theta x "
             f"{len(settings.phi_deg)} phi = {points} directions, {'x'.join(map(str, settings.orders))} harmonics, "
             f"{'x'.join(map(str, settings.keep))} kept; symmetry: {report.symmetry}",
             f"computed {report.chunks_computed} of {report.chunks_total} wavelength chunks ({report.chunks_reused} "
             f"resumed) in {report.seconds:.1f} s; {report.bytes_on_disk / 1e6:.2f} MB on disk",
             *report.notes]  # damaged chunks computed again, a table replaced
    if report.eigen_solves:
        lines.append(f"1D eigen-solves: {report.eigen_solves}, {report.eigen_refined / report.eigen_solves:.0%} refined "
                     f"from a neighbouring k_x (the rest solved afresh)")
    return "\n".join(lines)


def run_info(args: argparse.Namespace) -> int:
    from rcwa.table import format_summary, read_table_metadata, truncation_summary  # deferred: as in run_table
    from rcwa.table.store import read_progress

    data = table_info(args.table)
    meta = read_table_metadata(args.table)
    # the table's own truncation error (rcwa.table.truncation); None: not recorded (a table from before)
    data["truncation_error"] = truncation_summary(meta, None if meta.get("complete") else read_progress(Path(args.table)))
    text = "\n".join([format_table_info(data), *format_summary(data["truncation_error"])])
    print(json.dumps(data, indent=2) if args.json else text)
    return 0


ACTIONS: dict[str, Callable[[argparse.Namespace], int]] = {"solve": run_solve, "table": run_table, "info": run_info}
