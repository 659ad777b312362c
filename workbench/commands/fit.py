"""``workbench fit DATASET --scene SCENE --calibration calibration.json --out DIR``: the scene fit and its verdict
(reports.scene_fit.job)."""

from __future__ import annotations

import argparse
from pathlib import Path

from reports.scene_fit.verdict_record import Verdict
from workbench.commands.arguments import positive_number
from workbench.commands.cache import add_cache_option
from workbench.core.errors import UserInputError
from workbench.core.files import exclusive_output


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench fit``."""
    parser = commands.add_parser(
        "fit", help="fit the scene's free parameters ([fit]) to the photos' CD band edges: is it the model or the camera?",
        description="Fits the scene parameters the photos constrain (by default the CD's track pitch and tilt and the "
                    "light's centre; a scene's [fit] table names others, docs/scene_format.md) to the band edges of "
                    "the CD's fringes in every photo, through the grating-equation prediction weighted by the RCWA "
                    "efficiencies (no renderer in the loop), with standard deviations and correlations. Writes "
                    "DIR/scene_fit.json (parameters, residuals before and after, the verdict: consistent, model, camera "
                    "or unexplained, with the test's numbers) and DIR/fitted_scene.toml (a scene file any command "
                    "accepts).")
    parser.add_argument("dataset", metavar="DATASET", help="a dataset folder: photos/ and optionally brackets/")
    parser.add_argument("--scene", required=True, metavar="SCENE",
                        help="the scene the photos show, as designed (a built-in name or a TOML file)")
    parser.add_argument("--calibration", required=True, metavar="calibration.json",
                        help="the cameras of the photos (`workbench calibrate DATASET` writes it)")
    parser.add_argument("--out", required=True, metavar="DIR", help="the fit's folder")
    parser.add_argument("--photo", action="append", default=[], metavar="NAME",
                        help="fit to this photo of DATASET/photos only (repeatable; default: all)")
    parser.add_argument("--renders", default=None, metavar="DIR",
                        help="renders of the scene file through each photo's calibrated camera (DIR/NAME.exr, as "
                             "`workbench render` writes them for calibration's scenes/NAME.toml, and verify's render "
                             "stage): the forward model's own offsets (band edges, the CD's rim) are measured on them "
                             "and taken off the photos' (default: none, not corrected)")
    parser.add_argument("--supersample", type=positive_number(int), default=None, metavar="N",
                        help="sub-rays per pixel axis of the forward model (default: 1)")
    parser.add_argument("--step-nm", type=positive_number(float), default=None, metavar="NM",
                        help="the forward model's wavelength step (default: 5)")
    add_cache_option(parser)


def run(args: argparse.Namespace) -> int:
    from reports.scene_fit.job import FitInputs, run_fit  # deferred: pulls in scipy, cv2 and nlopt (start-up time)

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a folder for the fit", got=args.out)
    inputs = FitInputs(Path(args.dataset), args.scene, Path(args.calibration), out, tuple(args.photo),
                       renders=Path(args.renders) if args.renders else None)
    if args.supersample is not None:
        inputs.supersample = args.supersample
    if args.step_nm is not None:
        inputs.step_nm = args.step_nm
    with exclusive_output(out, "fit"):
        record = run_fit(inputs)
    print(format_fit(record))
    print(f"wrote {out / 'scene_fit.json'} and {out / 'fitted_scene.toml'} in {record['timings']['total']:.1f} s")
    return 0


def format_fit(record: dict) -> str:
    """The fit's parameters and verdict as lines of text."""
    lines = []
    for name, p in record["parameters"].items():
        std = p["std"] if isinstance(p["std"], list) else [p["std"]]
        if "tilt_deg" in p:
            lines.append(f"{name}: tilted {p['tilt_deg']:.3f} deg +- {p['tilt_std_deg']:.3f} from the file's normal")
        else:
            value = p["value"] if isinstance(p["value"], list) else [p["value"]]
            nominal = p["nominal"] if isinstance(p["nominal"], list) else [p["nominal"]]
            lines.append(f"{name}: {_numbers(nominal)} -> {_numbers(value)} {p['unit']} (std {_numbers(std)})")
    v = Verdict.from_json(record["verdict"])
    before, after = v.residuals_before_px, v.residuals_after_px
    lines.append(f"band-edge residuals: median {before.median:.2f} px before, {after.median:.2f} px after "
                 f"({after.count} edges)")
    test = v.noise_only
    lines.append(f"verdict: {v.outcome} ({v.why}; Wald statistic {test.statistic:.1f} on {test.dof} "
                 f"degrees of freedom, p = {test.p_value:.2g}, noise only)")
    for p in v.parameters:
        lines.append(f"  {p.component}: {p.nominal:.5g} -> {p.fitted:.5g} +- {p.std:.2g} ({p.sigmas:+.1f} std)")
    return "\n".join(lines)


def _numbers(values: list) -> str:
    return ", ".join(f"{v:.5g}" for v in values)
