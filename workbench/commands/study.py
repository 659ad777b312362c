"""``workbench study rcwa|render|calibrate|fit``: accuracy-versus-time studies (rcwa.table_study, renderer.render_study,
calibration.pose.study, reports.scene_fit.study)."""

from __future__ import annotations

import argparse
from collections.abc import Callable

import rcwa
import renderer.render_study
from rcwa.convergence import MIN_CURVE_ORDERS, CurveConfig
from rcwa.solve_cache import SolveCache, default_cache_path
from workbench.commands.arguments import STRUCTURE_HELP, count_argument, positive_numbers
from workbench.core.errors import UserInputError

CALIBRATE = "calibrate"


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add the ``study`` group: ``rcwa``, ``render``, ``calibrate`` and ``fit``."""
    study = commands.add_parser("study", help="accuracy-versus-time studies")
    studies = study.add_subparsers(dest="study_command", required=True)
    study_rcwa = studies.add_parser(
        "rcwa", help="truncation and interpolation error versus time for tables",
        description="1D structures: truncation and interpolation error versus time, and presets. 2D structures "
                    "(gold2d): each truncation N x N's error against the limit extrapolated in N, for Li's rule, the "
                    "normal-vector rule and (cells of rectangles) adaptive spatial resolution, versus seconds per "
                    "solve and per table (accuracy_time.csv, limits.csv, study_rcwa.png/.svg); raw solves are cached, "
                    "so a rerun with a higher --max-orders solves only "
                    "the new truncations.")
    study_rcwa.add_argument("structure", help=STRUCTURE_HELP)
    study_rcwa.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV and figures")
    study_rcwa.add_argument("--max-orders", type=count_argument(MIN_CURVE_ORDERS), default=CurveConfig.max_orders,
                            metavar="N", help=f"2D: the highest truncation N x N, odd (default {CurveConfig.max_orders}: "
                                              "about a minute with a cold cache; 41: about 8 minutes, 51: about half "
                                              "an hour)")
    study_rcwa.add_argument("--solve-cache", metavar="FILE", default=None,
                            help="2D: the JSON file of cached raw solves (default: NAME_raw.json in "
                                 "$RCWA_CONVERGENCE_CACHE, else in the workbench cache's convergence/ folder)")
    study_rcwa.add_argument("--quiet", action="store_true", help="no progress bar")

    study_render = studies.add_parser("render", help="render error versus time, paper against improved BWDF")
    study_render.add_argument("scene", nargs="?", default="cornell_cd",
                              help="a built-in scene name or a TOML file; its camera must see a CD or grating")
    study_render.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV and figures")
    study_render.add_argument("--quiet", action="store_true", help="no progress bar")
    _add_calibrate(studies)
    _add_fit(studies)


def _add_fit(studies: argparse._SubParsersAction) -> None:
    p = studies.add_parser(
        "fit", help="scene-fit error (period, tilt, light) versus time, against the scene the photos were made from",
        description="Fits DATASET's photos again and again with the forward model's resolution (sub-rays, wavelength "
                    "step), the share of band edges used and the number of photos varied one at a time, and compares "
                    "each fit with --truth-scene (the scene synth was given). Writes DIR/study_fit.json, study_fit.csv "
                    "and study_fit.png/.svg.")
    p.add_argument("dataset", metavar="DATASET", help="a dataset folder (photos/, brackets/)")
    p.add_argument("--scene", required=True, metavar="SCENE", help="the nominal scene, as `workbench fit` takes it")
    p.add_argument("--calibration", required=True, metavar="calibration.json", help="the photos' cameras")
    p.add_argument("--truth-scene", required=True, metavar="SCENE", help="the scene the photos were made from")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV, figures and each fit")
    p.add_argument("--renders", default=None, metavar="DIR",
                   help="renders of each photo's calibrated scene (as `workbench fit --renders`): every fit takes the "
                        "forward model's offsets off, and one more fit without them (default: none)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")


def _add_calibrate(studies: argparse._SubParsersAction) -> None:
    p = studies.add_parser(
        CALIBRATE, help="pose/FOV calibration error versus time on a synthetic dataset, against its truth",
        description="Fits every photo of DATASET (a `workbench synth` folder) with the pose refinement's settings "
                    "varied one at a time (fine-stage rounds and windows, fit resolution, render-check spp) and "
                    "compares with DATASET/truth.json; also the response curve's error against its knot count. "
                    "Writes DIR/study_calibrate.json, calibrate_settings.csv, calibrate_photos.csv, response_knots.csv "
                    "and study_calibrate.png/.svg.")
    p.add_argument("dataset", metavar="DATASET", help="a synthetic dataset folder with truth.json (`workbench synth`)")
    p.add_argument("--scene", required=True, metavar="SCENE", help="the scene the dataset shows (built-in name or file)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV and figures")
    p.add_argument("--scales", type=positive_numbers(float, "scales"), default=(1.0, 0.5, 0.25), metavar="S,...",
                   help="fit resolutions as fractions of the photo's (default 1,0.5,0.25)")
    p.add_argument("--spp", type=positive_numbers(int, "integers"), default=(4, 16, 64), metavar="N,...",
                   help="render-check samples per pixel (default 4,16,64)")
    p.add_argument("--rounds", type=positive_numbers(int, "integers"), default=(1, 2, 4), metavar="N,...",
                   help="fine-stage rounds per window; N rounds use the default windows' last N + 1 (default 1,2,4)")
    p.add_argument("--knots", type=positive_numbers(int, "integers"), default=(2, 3, 4, 6, 8), metavar="K,...",
                   help="knot counts of the response curve's parametric fit (default 2,3,4,6,8)")
    p.add_argument("--free-intrinsics", action="store_true",
                   help="fit the intrinsics from each photo instead of holding the board views' (the FOV refinement)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    return STUDIES[args.study_command](args)


def run_rcwa(args: argparse.Namespace) -> int:
    from rcwa.table_study import run_study  # deferred: pulls in scipy and shapely (start-up time)

    structure = rcwa.load_structure(args.structure)
    if structure.dimension == 2:
        return run_rcwa_2d(args, structure)
    data = run_study(structure, args.out, progress=not args.quiet)
    print(f"wrote {args.out}/study_rcwa.json, truncation.csv, interpolation.csv, presets.csv, study_rcwa.png/.svg")
    for p in data["presets"]:
        if p["reachable"]:
            print(f"target {p['target_error']:g}: {p['orders']} harmonics, {p['grid']} grid, {p['step_deg']:g} deg step, "
                  f"~{p['estimated_table_seconds']:.0f} s for a full table, {p['table_bytes'] / 1e6:.2f} MB")
        else:
            print(f"target {p['target_error']:g}: not reached by the measured settings")
    return 0


def run_rcwa_2d(args: argparse.Namespace, structure: rcwa.Structure) -> int:
    from rcwa.table_study import run_convergence_study  # deferred: as run_rcwa

    if args.max_orders % 2 == 0:
        raise UserInputError("the truncation must be odd (symmetric about order 0)", field="--max-orders",
                             expected=f"an odd integer >= {MIN_CURVE_ORDERS}", got=args.max_orders)
    cache = SolveCache(args.solve_cache or default_cache_path(structure.name), structure)
    cfg = CurveConfig(max_orders=args.max_orders, max_timed_orders=min(args.max_orders, CurveConfig.max_timed_orders))
    data = run_convergence_study(structure, args.out, cfg, cache, progress=not args.quiet)
    print(f"wrote {args.out}/study_rcwa.json, accuracy_time.csv, limits.csv, study_rcwa.png/.svg (raw solves: {cache.path})")
    print(f"limits' largest error bar {data['reference_error']:.2g}")
    print(f"{'rule':>5} {'N':>3} {'max error':>10} {'s/solve':>8} {'s/table':>10}")
    for r in data["rows"]:
        mark = "~" if r["table_seconds_estimated"] else " "
        print(f"{r['rule']:>5} {r['orders']:>3} {r['max_error']:>10.2e} {r['seconds_per_solve']:>8.2f} "
              f"{mark}{r['seconds_per_table']:>9.3g}")
    return 0


def run_render(args: argparse.Namespace) -> int:
    data = renderer.render_study.run_render_study(args.scene, args.out, progress=not args.quiet)
    print(f"wrote {args.out}/study_render.json, the CSV files and study_render.png/.svg")
    for e in data["energy"]:
        print(f"furnace energy, {e['mode']} mode: {e['energy']:.4f}")
    return 0


def fine_settings(rounds: tuple[int, ...]) -> tuple[tuple[int, tuple[float, ...]], ...]:
    """Each rounds count with a window schedule: the default's last ``min(n + 1, all)`` windows
    (fewer rounds, fewer windows: the cheap end of the fine stage)."""
    from calibration.pose.calibrate import PoseSettings  # deferred: pulls in the renderer, scipy and cv2 (start-up time)

    windows = PoseSettings().fine_windows_px
    return tuple((n, windows[-min(n + 1, len(windows)):]) for n in rounds)


def run_calibrate(args: argparse.Namespace) -> int:
    from calibration.pose.study import CalibrateStudyConfig, run_calibrate_study  # deferred: as fine_settings

    cfg = CalibrateStudyConfig(fine=fine_settings(args.rounds), scales=args.scales, render_spp=args.spp, knots=args.knots,
                               free_intrinsics=args.free_intrinsics)
    data = run_calibrate_study(args.dataset, args.scene, args.out, cfg, progress=not args.quiet)
    print(f"wrote {args.out}/study_calibrate.json, calibrate_settings.csv, calibrate_photos.csv, response_knots.csv and "
          f"study_calibrate.png/.svg in {data['timings']['total_s']:.0f} s (intrinsics: {data['intrinsics']})")
    print(f"{'factor':>10} {'rounds':>6} {'scale':>5} {'spp':>4} {'seconds':>8} {'rot deg':>8} {'centre mm':>9} "
          f"{'FOV deg':>8} {'pp %':>6} {'expo %':>7}")
    for r in data["error_vs_time"]:
        print(f"{r['factor']:>10} {r['fine_rounds']:>6} {r['scale']:>5g} {r['render_spp']:>4} {r['seconds']:>8.2f} "
              f"{r['rotation_deg']:>8.4f} {r['centre_mm']:>9.3f} {r['fov_deg']:>8.4f} {r['principal_point_pct']:>6.3f} "
              f"{r['exposure_pct']:>7.3f}")
    for k in data["response_knots"]:
        print(f"response, {k['knots']} knots: RMS {k['response_rms_pct']:.3f} % in {k['seconds']:.2f} s")
    return 0


def run_fit(args: argparse.Namespace) -> int:
    from pathlib import Path

    from reports.scene_fit.study import run_fit_study  # deferred: pulls in scipy, cv2 and nlopt (start-up time)

    data = run_fit_study(Path(args.dataset), args.scene, Path(args.calibration), args.truth_scene, Path(args.out),
                         progress=not args.quiet, renders=Path(args.renders) if args.renders else None)
    print(f"wrote {args.out}/study_fit.json, study_fit.csv and study_fit.png/.svg in {data['timings']['total_s']:.0f} s")
    return 0


STUDIES: dict[str, Callable[[argparse.Namespace], int]] = {"rcwa": run_rcwa, "render": run_render, CALIBRATE: run_calibrate,
                                                          "fit": run_fit}
