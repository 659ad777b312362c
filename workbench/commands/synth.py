"""``workbench synth SCENE --out DIR``: synthetic raw photographs with known truth (datasets_synthetic.synth)."""

from __future__ import annotations

import argparse
from pathlib import Path

from workbench.commands.arguments import SCENE_HELP, SEED_MAX, count_argument
from workbench.commands.cache import add_cache_option
from workbench.core.errors import UserInputError


def add_parser(commands: argparse._SubParsersAction) -> None:
    """Add ``workbench synth``."""
    synth = commands.add_parser("synth", help="synthetic raw photographs (DNG) with known truth")
    synth.add_argument("scene", help=SCENE_HELP)
    synth.add_argument("--out", required=True, metavar="DIR",
                       help="the dataset folder (photos/, brackets/, calibration/, truth.json)")
    synth.add_argument("--seed", type=count_argument(0, SEED_MAX), default=0,
                       help="seed of the hidden camera and the noise: same seed, same bytes "
                            "(bit for bit with WORKBENCH_RENDER_THREADS=1)")
    synth.add_argument("--preset", choices=["draft", "full", "large"], default="draft",
                       help="draft: 640 x 480, 2 views, 20 board views (about a minute); "
                            "full: 978 x 734, 3 views (about 14 minutes); large: one 6000 x 4000 view at 2 spp and "
                            "4 board views at 1 spp, for reports of large photos (about 5 minutes)")
    synth.add_argument("--force", action="store_true", help="replace an existing dataset in DIR")
    synth.add_argument("--vignetting", metavar="PR,PG,PB", type=_powers, default=None,
                       help="give the lens vignetting: each channel darkened by cos^p of the field angle (4: the cos^4 "
                            "law of an ideal lens), e.g. 3.8,4,4.4; truth.json's sensor records it (default: none)")
    add_cache_option(synth)


def _powers(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(part) for part in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected three numbers PR,PG,PB, got {text!r}") from None


def run(args: argparse.Namespace) -> int:
    from datasets_synthetic.synth import synth  # deferred: pulls in the renderer, scipy and cv2 (start-up time)

    if Path(args.out).exists() and not Path(args.out).is_dir():
        raise UserInputError("is a file, not a folder", field="--out", expected="a new or dataset folder", got=args.out)
    truth = synth(args.scene, args.out, seed=args.seed, preset=args.preset, force=args.force, vignetting=args.vignetting)
    n = {k: sum(1 for name in truth["exposure_time_s"] if name.startswith(k)) for k in ("view", "ev", "board")}
    print(f"wrote {args.out}: {n['view']} photos (photos/*.dng), {n['ev']} bracket files (brackets/*.dng, *.jpg), "
          f"{n['board']} calibration views (calibration/*.dng), truth.json and run.json "
          f"(seed {truth['seed']}, {truth['preset']})")
    return 0
