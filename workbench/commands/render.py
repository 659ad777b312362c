"""``workbench render SCENE --out PATH.exr``: a scene to linear camera RGB (renderer.render)."""

from __future__ import annotations

import argparse
import sys

from workbench.commands.arguments import SCENE_HELP, SEED_MAX, count_argument, positive_number, resolution_argument
from workbench.commands.cache import add_cache_option
from workbench.core.executor import DaskExecutor

TARGETS = ("report",)  # renderer.render_target.TARGETS (not imported here: the renderer pulls in mitsuba's start-up)


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench render``."""
    render = commands.add_parser("render", help="render a scene to linear camera RGB (EXR, PNG preview, JSON)")
    render.add_argument("scene", help=SCENE_HELP)
    render.add_argument("--out", required=True, metavar="PATH.exr",
                        help="the linear camera-RGB EXR; the PNG preview and JSON sidecar go beside it")
    render.add_argument("--preset", choices=["draft", "paper"], default="draft",
                        help="draft: the scene camera's resolution, 256 spp; paper: the paper's frame, 978 x 734 at 2045 spp")
    render.add_argument("--spp", type=count_argument(1), metavar="N",
                        help="samples per pixel everywhere (default: the preset's); not with --target")
    render.add_argument("--target", choices=list(TARGETS), metavar="report",
                        help="report: sample each region until what the report measures there is good enough (the CD's "
                             "band edges to 0.1 px, rendered as its own crop, at most 1024 spp (draft) or 4096 (paper); "
                             "the walls' photometric scale to 0.2 %%; 64 spp elsewhere; the preset's spp caps the frame); "
                             "the sidecar records each region's spp and noise (default: none, the fixed render)")
    render.add_argument("--resolution", type=resolution_argument, metavar="WxH", help="image size (default: the preset's)")
    render.add_argument("--integrator", choices=["path", "direct"], default="path",
                        help="path: global illumination; direct: light sources only, as the paper's second mode")
    render.add_argument("--mode", choices=["paper", "improved"], default="improved",
                        help="BWDF sampling: paper reproduces Lange et al. 2021 Eqs. 2-5; improved is unbiased and less noisy")
    render.add_argument("--seed", type=count_argument(0, SEED_MAX), default=0, help="random seed of the first pass")
    render.add_argument("--scheduler", metavar="ADDRESS",
                        help="render the passes on this dask.distributed scheduler (default: in this process)")
    render.add_argument("--workers", type=count_argument(1), metavar="N",
                        help="start a local dask cluster with N worker processes (default: none, in this process)")
    white = render.add_mutually_exclusive_group()
    white.add_argument("--preview-white", type=positive_number(float), metavar="LEVEL",
                       help="the PNG preview shows this white-balanced linear value as white, so renders made with "
                            "the same LEVEL compare by eye (default: each render's own 99.5th percentile)")
    white.add_argument("--preview-like", metavar="RENDER.json",
                       help="the PNG preview takes the white level another render's preview used (its sidecar; "
                            "default: none, the render's own)")
    render.add_argument("--quiet", action="store_true", help="no progress bar")
    render.add_argument("--force", action="store_true", help="replace a different render (its EXR, PNG and JSON) at --out")
    render.add_argument("--no-plan", action="store_true",
                        help="build whole efficiency tables instead of the parts this camera needs (`workbench plan`)")
    add_cache_option(render)


def run(args: argparse.Namespace) -> int:
    from renderer.preview import PreviewRequest, white_level_of
    from renderer.render import black_warning, render, summary  # deferred: the renderer pulls in scipy and cv2 (start-up time)

    options = dict(preset=args.preset, spp=args.spp, resolution=args.resolution, integrator=args.integrator,
                   mode=args.mode, seed=args.seed, progress=not args.quiet, force=args.force, plan=not args.no_plan,
                   target=args.target, preview=PreviewRequest())
    if args.preview_white is not None:
        options["preview"] = PreviewRequest(args.preview_white, "--preview-white")
    elif args.preview_like is not None:
        options["preview"] = PreviewRequest(white_level_of(args.preview_like), args.preview_like)
    if args.scheduler or args.workers:
        with DaskExecutor(args.scheduler, args.workers) as executor:
            info = render(args.scene, args.out, executor=executor, **options)
    else:
        info = render(args.scene, args.out, **options)
    warning = black_warning(info)
    if warning is not None:
        print(warning, file=sys.stderr)
    print(summary(info))  # also says when it was resumed or served from a finished identical render
    return 0
