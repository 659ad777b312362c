"""The ``workbench`` command line.

Every user error ends with ``error: <what, where, expected>`` on stderr and exit status 2,
never a Python traceback.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from workbench import cli_calibrate, cli_study, cli_verify
from workbench.catalog import KINDS
from workbench.cli_arguments import count_argument
from workbench.cli_cache import add_cache_option, apply_cache_option
from workbench.cli_cache import add_parsers as add_cache_parsers
from workbench.cli_cache import run as run_cache
from workbench.cli_report import add_parsers as add_report_parsers
from workbench.cli_report import run as run_report
from workbench.core.errors import UserInputError


def _orders_argument(text: str) -> int | tuple[int, ...]:
    parts = text.split(",")
    try:
        values = tuple(int(p) for p in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or NX,NY (odd integers), got {text!r}") from None
    return values[0] if len(values) == 1 else values


def _resolution_argument(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
        if w < 1 or h < 1:
            raise ValueError
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WxH with positive integers (e.g. 640x480), got {text!r}") from None
    return w, h


def _pair_argument(text: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected LO,HI in degrees, got {text!r}") from None
    return lo, hi


DESCRIPTION = """\
A photograph-validation and calibration workbench for wave-optical rendering: rigorous
diffraction efficiencies of periodic surfaces (RCWA), spectral renders of them in a scene
(Mitsuba 3), synthetic raw photographs with known truth, and camera calibration from
photographs. `workbench list scenes` shows the built-in scenes; `workbench demo` runs the
main job on the defaults. Caches and outputs: see the README."""

SEED_MAX = 2**32 - 1  # Mitsuba's and numpy's seeds are unsigned 32-bit


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Shows each option's default where it has a meaningful one (not None or False)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        empty = action.default is None or action.default is False or action.default is argparse.SUPPRESS
        if empty or action.default == [] or "default" in text:  # []: a repeatable option given no time
            return text
        if action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE):
            return f"{text} (default: %(default)s)"
        return text


class _Parser(argparse.ArgumentParser):
    """Every (sub)command's parser shows defaults and keeps the description's line breaks."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)


def _build_parser() -> argparse.ArgumentParser:
    from workbench import __version__

    parser = _Parser(prog="workbench", description=DESCRIPTION)
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    add_cache_option(parser, top_level=True)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    rcwa_parser = commands.add_parser("rcwa", help="rigorous coupled-wave analysis")
    rcwa_commands = rcwa_parser.add_subparsers(dest="rcwa_command", required=True)
    solve = rcwa_commands.add_parser("solve", help="diffraction efficiencies for one incident plane wave")
    solve.add_argument("structure", help=STRUCTURE_HELP)
    solve.add_argument("--wavelength", type=float, required=True, metavar="NM", help="vacuum wavelength in nm")
    solve.add_argument("--theta", type=float, default=0.0, metavar="DEG", help="polar angle of incidence (default 0)")
    solve.add_argument("--phi", type=float, default=0.0, metavar="DEG", help="azimuth of incidence from +x (default 0)")
    solve.add_argument("--orders", type=_orders_argument, required=True, metavar="N|NX,NY",
                       help="retained harmonics per direction (odd)")
    solve.add_argument("--pol", choices=["s", "p", "unpolarized"], default="unpolarized",
                       help="incident polarization; unpolarized is the mean of s and p")
    solve.add_argument("--factorization", choices=["auto", "li", "nv", "laurent"], default="auto", help=FACTORIZATION_HELP)
    solve.add_argument("--stack", choices=["etm", "smatrix"], default="etm",
                       help="layer stacking: enhanced transmittance matrix (default) or Redheffer star product")
    solve.add_argument("--json", action="store_true", help="print one JSON object instead of a table")

    table = rcwa_commands.add_parser("table", help="efficiency table over wavelength x incidence angles (for rendering)")
    table.add_argument("structure", help=STRUCTURE_HELP)
    table.add_argument("--out", required=True, metavar="PATH", help="table directory (zarr); resumed if unfinished")
    table.add_argument("--preset", choices=["paper", "draft", "fine"], default="paper", help=PRESET_HELP)
    table.add_argument("--theta-step", type=float, metavar="DEG", help="polar-angle step (default: the preset's)")
    table.add_argument("--phi-step", type=float, metavar="DEG", help="azimuth step (default: the preset's)")
    table.add_argument("--wavelengths", metavar="START:STOP:COUNT",
                       help="nm, inclusive (e.g. 400:700:31), or NM,NM,... (default: the preset's)")
    table.add_argument("--theta-range", type=_pair_argument, metavar="LO,HI", help="polar angles to cover (deg; default: 0,90)")
    table.add_argument("--phi-range", type=_pair_argument, metavar="LO,HI",
                       help="azimuths to cover (deg, in the stored range; default: all of it)")
    table.add_argument("--orders", type=_orders_argument, metavar="N|NX,NY",
                       help="retained harmonics (odd; default: the preset's for the structure's dimension)")
    table.add_argument("--keep-orders", type=_orders_argument, metavar="N|NX,NY",
                       help="orders stored (odd, <= --orders; default: the preset's, at most --orders)")
    table.add_argument("--pol", choices=["unpolarized", "s", "p", "all"], default="unpolarized",
                       help="polarizations stored; all = s, p and their mean")
    table.add_argument("--reflection-only", action="store_true", help="store R only, even where the substrate transmits")
    table.add_argument("--both-sides", action="store_true", help="also light from below (see-through elements)")
    table.add_argument("--factorization", choices=["auto", "li", "nv", "laurent"], default="auto", help=FACTORIZATION_HELP)
    table.add_argument("--no-symmetry", action="store_true", help="compute the whole azimuth range")
    table.add_argument("--threads", type=int, default=None, help="solver threads (default: all cores)")
    table.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the chunks on this dask.distributed scheduler (default: threads in this process)")
    table.add_argument("--workers", type=int, metavar="N",
                       help="start a local dask cluster with N worker processes (default: none, threads in this process)")
    table.add_argument("--force", action="store_true", help="overwrite a different table at --out")
    table.add_argument("--quiet", action="store_true", help="no progress bar")

    render = commands.add_parser("render", help="render a scene to linear camera RGB (EXR, PNG preview, JSON)")
    render.add_argument("scene", help=SCENE_HELP)
    render.add_argument("--out", required=True, metavar="PATH.exr",
                        help="the linear camera-RGB EXR; the PNG preview and JSON sidecar go beside it")
    render.add_argument("--preset", choices=["draft", "paper"], default="draft",
                        help="draft: the scene camera's resolution, 256 spp; paper: the paper's frame, 978 x 734 at 2045 spp")
    render.add_argument("--spp", type=count_argument(1), metavar="N", help="samples per pixel (default: the preset's)")
    render.add_argument("--resolution", type=_resolution_argument, metavar="WxH", help="image size (default: the preset's)")
    render.add_argument("--integrator", choices=["path", "direct"], default="path",
                        help="path: global illumination; direct: light sources only, as the paper's second mode")
    render.add_argument("--mode", choices=["paper", "improved"], default="improved",
                        help="BWDF sampling: paper reproduces Lange et al. 2021 Eqs. 2-5; improved is unbiased and less noisy")
    render.add_argument("--seed", type=count_argument(0, SEED_MAX), default=0, help="random seed of the first pass")
    render.add_argument("--scheduler", metavar="ADDRESS",
                        help="render the passes on this dask.distributed scheduler (default: in this process)")
    render.add_argument("--workers", type=int, metavar="N",
                        help="start a local dask cluster with N worker processes (default: none, in this process)")
    render.add_argument("--quiet", action="store_true", help="no progress bar")
    render.add_argument("--force", action="store_true", help="replace a different render (its EXR, PNG and JSON) at --out")
    render.add_argument("--no-plan", action="store_true",
                        help="build whole efficiency tables instead of the parts this camera needs (`workbench plan`)")
    add_cache_option(render)

    synth = commands.add_parser("synth", help="synthetic raw photographs (DNG) with known truth")
    synth.add_argument("scene", help=SCENE_HELP)
    synth.add_argument("--out", required=True, metavar="DIR",
                       help="the dataset folder (photos/, brackets/, calibration/, truth.json)")
    synth.add_argument("--seed", type=count_argument(0, SEED_MAX), default=0,
                       help="seed of the hidden camera and the noise: same seed, same bytes")
    synth.add_argument("--preset", choices=["draft", "full"], default="draft",
                       help="draft: 640 x 480, 2 views, 20 board views (about a minute); "
                            "full: 978 x 734, 3 views (about 14 minutes)")
    synth.add_argument("--force", action="store_true", help="replace an existing dataset in DIR")
    add_cache_option(synth)

    study = commands.add_parser("study", help="accuracy-versus-time studies")
    study_commands = study.add_subparsers(dest="study_command", required=True)
    study_rcwa = study_commands.add_parser("rcwa", help="truncation and interpolation error versus time for tables")
    study_rcwa.add_argument("structure", help=STRUCTURE_HELP)
    study_rcwa.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV and figures")
    study_rcwa.add_argument("--quiet", action="store_true", help="no progress bar")

    study_render = study_commands.add_parser("render", help="render error versus time, paper against improved BWDF")
    study_render.add_argument("scene", nargs="?", default="cornell_cd",
                              help="a built-in scene name or a TOML file; its camera must see a CD or grating")
    study_render.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV and figures")
    study_render.add_argument("--quiet", action="store_true", help="no progress bar")
    cli_study.add_calibrate(study_commands)

    demo = commands.add_parser("demo", help="the main job on the built-in defaults: a synthetic dataset of cornell_cd, then "
                        "verify and score on it, in out/demo/", description="Writes the default synthetic dataset "
                        "(workbench synth cornell_cd) to out/demo/dataset, runs workbench verify on it (first photo) into "
                        "out/demo/run and scores the calibration against the truth; ends with the report's path.")
    add_cache_option(demo)

    plan = commands.add_parser("plan", help="what a scene needs simulated: tables, orders, angles, wavelengths, cost",
                               description="Reads the scene and decides, before anything runs, which efficiency tables "
                               "its render needs (R, T, which sides), which orders can reach the camera, which part of each "
                               "table's (wavelength, theta, phi) grid the camera's rays can look up, the camera's "
                               "wavelength range, and which glass dispersion matters; with the cost measured here.")
    plan.add_argument("scene", help=SCENE_HELP)
    plan.add_argument("--json", action="store_true", help="print one JSON object instead of the table")

    listing = commands.add_parser("list", help="the built-in structures, scenes, materials and cameras")
    listing.add_argument("kind", choices=list(KINDS), help="what to list")
    add_cache_parsers(commands)
    add_report_parsers(commands)
    cli_calibrate.add_parsers(commands)
    cli_verify.add_parsers(commands)

    info = rcwa_commands.add_parser("info", help="what a table holds: grid, settings, size, symmetry, integrity")
    info.add_argument("table", metavar="TABLE", help="a table folder written by `workbench rcwa table`")
    info.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    return parser


SCENE_HELP = "a built-in scene (`workbench list scenes`) or a scene file (docs/scene_format.md)"
STRUCTURE_HELP = "a built-in structure (`workbench list structures`) or a structure file (docs/structure_format.md)"
FACTORIZATION_HELP = ("Fourier factorization rule: auto = li for 1D and for 2D cells of rectangles only, nv for other "
                      "2D cells; li = Li's inverse rule (Li 1996 in 1D, 1997 in 2D); nv = the normal vector method; "
                      "laurent = the plain product rule, for comparison")
PRESET_HELP = ("paper: 31 wavelengths 400-700 nm, 2 deg steps in theta and phi, 61 (1D) or 11x11 (2D) harmonics "
               "(the CD takes about 70-95 s here); draft: 11 wavelengths, 5/10 deg steps, 31 or 7x7 harmonics "
               "(seconds); fine: 81 wavelengths 380-780 nm, 1 deg steps, 81 or 15x15 harmonics")


def _run_rcwa_solve(args: argparse.Namespace) -> int:
    import rcwa
    from workbench.report_text import solve_table

    structure = rcwa.load_structure(args.structure)
    result = rcwa.solve(structure, args.wavelength, args.theta, args.phi, args.orders, args.pol, args.factorization,
                        args.stack)
    print(json.dumps(result.to_dict(), indent=2) if args.json else solve_table(result))
    return 0


def _run_rcwa_table(args: argparse.Namespace) -> int:
    import rcwa
    from rcwa.table import build_table, settings_for

    structure = rcwa.load_structure(args.structure)
    settings = settings_for(
        structure, args.preset, theta_step=args.theta_step, phi_step=args.phi_step, wavelengths=args.wavelengths,
        orders=args.orders, keep=args.keep_orders, pol=args.pol, reflection_only=args.reflection_only,
        both_sides=args.both_sides, factorization=args.factorization, use_symmetry=not args.no_symmetry,
        theta_range=args.theta_range, phi_range=args.phi_range,
    )
    if args.threads is not None and args.threads < 1:
        raise UserInputError("must be at least 1", field="--threads", got=args.threads)
    if args.workers is not None and args.workers < 1:
        raise UserInputError("must be at least 1", field="--workers", got=args.workers)
    if args.scheduler or args.workers:
        from workbench.core.executor import DaskExecutor

        with DaskExecutor(args.scheduler, args.workers) as executor:
            report = build_table(structure, settings, args.out, progress=not args.quiet, force=args.force, executor=executor)
    else:
        report = build_table(structure, settings, args.out, threads=args.threads, progress=not args.quiet, force=args.force)
    points = len(settings.wavelengths_nm) * len(settings.theta_deg) * len(settings.phi_deg)
    if report.cached:
        print(f"{args.out}: up to date (request {report.key[:12]}), served from the cache in {report.seconds * 1e3:.1f} ms")
        return 0
    print(f"{args.out}: {structure.name}, {len(settings.wavelengths_nm)} wavelengths x {len(settings.theta_deg)} theta x "
          f"{len(settings.phi_deg)} phi = {points} directions, {'x'.join(map(str, settings.orders))} harmonics, "
          f"{'x'.join(map(str, settings.keep))} kept; symmetry: {report.symmetry}")
    print(f"computed {report.chunks_computed} of {report.chunks_total} wavelength chunks ({report.chunks_reused} resumed) "
          f"in {report.seconds:.1f} s; {report.bytes_on_disk / 1e6:.2f} MB on disk")
    for note in report.notes:  # damaged chunks computed again, a table replaced
        print(note)
    if report.eigen_solves:
        print(f"1D eigen-solves: {report.eigen_solves}, {report.eigen_refined / report.eigen_solves:.0%} refined from a "
              f"neighbouring k_x (the rest solved afresh)")
    return 0


def _run_study_rcwa(args: argparse.Namespace) -> int:
    import rcwa
    from rcwa.study import run_study

    structure = rcwa.load_structure(args.structure)
    if structure.dimension != 1:
        raise UserInputError("the study covers 1D structures for now", field="structure", got=args.structure)
    data = run_study(structure, args.out, progress=not args.quiet)
    print(f"wrote {args.out}/study_rcwa.json, truncation.csv, interpolation.csv, presets.csv, study_rcwa.png/.svg")
    for p in data["presets"]:
        if p["reachable"]:
            print(f"target {p['target_error']:g}: {p['orders']} harmonics, {p['grid']} grid, {p['step_deg']:g} deg step, "
                  f"~{p['estimated_table_seconds']:.0f} s for a full table, {p['table_bytes'] / 1e6:.2f} MB")
        else:
            print(f"target {p['target_error']:g}: not reached by the measured settings")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # quiet when piped into head or less
    from workbench.cli_calibrate_pose import route_dataset

    parser = _build_parser()
    argv = route_dataset(sys.argv[1:] if argv is None else list(argv), tuple(cli_calibrate.CALIBRATE_STEPS))
    args = parser.parse_args(argv)
    try:
        apply_cache_option(args)
        if args.command == "cache":
            return run_cache(args)
        if args.command == "report":
            return run_report(args)
        if args.command == "rcwa" and args.rcwa_command == "solve":
            return _run_rcwa_solve(args)
        if args.command == "rcwa" and args.rcwa_command == "table":
            return _run_rcwa_table(args)
        if args.command == "render":
            from renderer.render import render as run_render

            kwargs = dict(preset=args.preset, spp=args.spp, resolution=args.resolution, integrator=args.integrator,
                          mode=args.mode, seed=args.seed, progress=not args.quiet, force=args.force, plan=not args.no_plan)
            if args.workers is not None and args.workers < 1:
                raise UserInputError("must be at least 1", field="--workers", got=args.workers)
            if args.scheduler or args.workers:
                from workbench.core.executor import DaskExecutor

                with DaskExecutor(args.scheduler, args.workers) as executor:
                    info = run_render(args.scene, args.out, executor=executor, **kwargs)
            else:
                info = run_render(args.scene, args.out, **kwargs)
            from renderer.render import summary as render_summary

            print(render_summary(info))  # also says when it was resumed or served from a finished identical render
            return 0
        if args.command == "synth":
            from datasets_synthetic.synth import synth

            if Path(args.out).exists() and not Path(args.out).is_dir():
                raise UserInputError("is a file, not a folder", field="--out", expected="a new or dataset folder", got=args.out)
            truth = synth(args.scene, args.out, seed=args.seed, preset=args.preset, force=args.force)
            n = {k: sum(1 for name in truth["exposure_time_s"] if name.startswith(k)) for k in ("view", "ev", "board")}
            print(f"wrote {args.out}: {n['view']} photos (photos/*.dng), {n['ev']} bracket files (brackets/*.dng, *.jpg), "
                  f"{n['board']} calibration views (calibration/*.dng), truth.json and run.json "
                  f"(seed {truth['seed']}, {truth['preset']})")
            return 0
        if args.command == "study" and args.study_command == "rcwa":
            return _run_study_rcwa(args)
        if args.command == "study" and args.study_command == cli_study.CALIBRATE:
            return cli_study.run_calibrate(args)
        if args.command == "study" and args.study_command == "render":
            from renderer.study import run_render_study

            data = run_render_study(args.scene, args.out, progress=not args.quiet)
            print(f"wrote {args.out}/study_render.json, the CSV files and study_render.png/.svg")
            for e in data["energy"]:
                print(f"furnace energy, {e['mode']} mode: {e['energy']:.4f}")
            return 0
        if args.command == "plan":
            from renderer.planner import format_plan, plan_scene
            from renderer.scene import load_scene

            result = plan_scene(load_scene(args.scene))
            print(json.dumps(result.to_json(), indent=2) if args.json else format_plan(result))
            return 0
        if args.command == "list":
            from workbench.catalog import format_builtins

            print(format_builtins(args.kind))
            return 0
        if args.command == "rcwa" and args.rcwa_command == "info":
            from workbench.catalog import format_table_info, table_info

            data = table_info(args.table)
            print(json.dumps(data, indent=2) if args.json else format_table_info(data))
            return 0
        if args.command in cli_calibrate.COMMANDS:
            return cli_calibrate.run(args)
        if args.command in cli_verify.COMMANDS:
            return cli_verify.run(args)
        if args.command == "demo":
            from workbench.demo import run_demo

            return run_demo()
    except UserInputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    parser.error("unknown command")
    return 2


if __name__ == "__main__":
    sys.exit(main())
