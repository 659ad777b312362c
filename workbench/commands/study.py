"""``workbench study calibrate DATASET --scene SCENE --out DIR`` (calibration.study).

workbench/cli.py adds the parser to its ``study`` group with ``add_calibrate`` and runs it
with ``run_calibrate``; user errors raise UserInputError (``error: ...``, exit status 2).
"""

from __future__ import annotations

import argparse

CALIBRATE = "calibrate"


def _numbers(kind, name: str):
    def parse(text: str) -> tuple:
        try:
            values = tuple(kind(v) for v in text.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected comma-separated {name}, got {text!r}") from None
        if not values or not all(v > 0 for v in values):
            raise argparse.ArgumentTypeError(f"expected positive {name}, got {text!r}")
        return values
    return parse


def add_calibrate(study_commands) -> None:
    p = study_commands.add_parser(
        CALIBRATE, help="pose/FOV calibration error versus time on a synthetic dataset, against its truth",
        description="Fits every photo of DATASET (a `workbench synth` folder) with the pose refinement's settings "
                    "varied one at a time (fine-stage rounds and windows, fit resolution, render-check spp) and "
                    "compares with DATASET/truth.json; also the response curve's error against its knot count. "
                    "Writes DIR/study_calibrate.json, calibrate_settings.csv, calibrate_photos.csv, response_knots.csv "
                    "and study_calibrate.png/.svg.")
    p.add_argument("dataset", metavar="DATASET", help="a synthetic dataset folder with truth.json (`workbench synth`)")
    p.add_argument("--scene", required=True, metavar="SCENE", help="the scene the dataset shows (built-in name or file)")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the JSON, CSV and figures")
    p.add_argument("--scales", type=_numbers(float, "scales"), default=(1.0, 0.5, 0.25), metavar="S,...",
                   help="fit resolutions as fractions of the photo's (default 1,0.5,0.25)")
    p.add_argument("--spp", type=_numbers(int, "integers"), default=(4, 16, 64), metavar="N,...",
                   help="render-check samples per pixel (default 4,16,64)")
    p.add_argument("--rounds", type=_numbers(int, "integers"), default=(1, 2, 4), metavar="N,...",
                   help="fine-stage rounds per window; N rounds use the default windows' last N + 1 (default 1,2,4)")
    p.add_argument("--knots", type=_numbers(int, "integers"), default=(2, 3, 4, 6, 8), metavar="K,...",
                   help="knot counts of the response curve's parametric fit (default 2,3,4,6,8)")
    p.add_argument("--free-intrinsics", action="store_true",
                   help="fit the intrinsics from each photo instead of holding the board views' (the FOV refinement)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def fine_settings(rounds: tuple[int, ...]) -> tuple[tuple[int, tuple[float, ...]], ...]:
    """Each rounds count with a window schedule: the default's last ``min(n + 1, all)`` windows
    (fewer rounds, fewer windows: the cheap end of the fine stage)."""
    from calibration.pose import PoseSettings

    windows = PoseSettings().fine_windows_px
    return tuple((n, windows[-min(n + 1, len(windows)):]) for n in rounds)


def run_calibrate(args: argparse.Namespace) -> int:
    from calibration.study import CalibrateStudyConfig, run_calibrate_study

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

