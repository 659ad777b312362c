"""`calibrate pose` refuses a photo that does not show the scene (calibration/pose/edge_fit.py: edge_coverage,
check_coverage; issue 45 item 1).

The test that can say no is the coverage: the share of the scene's projected edge samples where the photo shows an
edge at the fitted camera. Measured: 0.918-0.993 on the draft dataset's photos of the scene (views and bracket
frames, board intrinsics or free: 18 fits, none refused), 0.25-0.62 on real photos that show no box (13
chessboard_right views with intrinsics of the scene's lens at their size or free, sony frame01, bumblebee left01,
the colour chart: right01 0.57, the colour chart 0.26). MIN_COVERAGE = 0.75 lies between. Real
photos that do not show the box must be refused with exit 2 and one `error:` line naming the photo and the test,
with and without the render check, before anything is written or rendered. That a photo of the scene is not
refused is asserted where test_pose.py fits its synthetic photos (the exact raster, the dataset's views).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from calibration.pose.calibrate import PoseSettings, calibrate_pose
from calibration.pose.edge_fit import MIN_COVERAGE
from workbench.core.errors import UserInputError

REAL = Path("/work/shared/data/real")
CHESSBOARD = REAL / "chessboard_right" / "right01.jpg"   # 640 x 480 JPEG: a chessboard, no box
COLOUR_CHART = REAL / "colorchart.dng"                   # 1734 x 1156 raw: a colour chart, no box
needs_real = pytest.mark.skipif(not CHESSBOARD.exists() or not COLOUR_CHART.exists(), reason="the shared real photos")


def scene_lens_intrinsics(path: Path, width: int, height: int) -> Path:
    """intrinsics.json of cornell_cd's lens (35 mm on 25 mm film: fx = 1.4 w) at the photo's size: the
    fit then starts where it would for a photo of the scene taken with that lens."""
    focal = 1.4 * width
    path.write_text(json.dumps({"width": width, "height": height, "fx": focal, "fy": focal, "cx": (width - 1) / 2,
                                "cy": (height - 1) / 2, "dist": [0.0] * 5}))
    return path


def _coverage(message: str) -> float:
    found = re.search(r"coverage (\d\.\d+) of its expected edges", message)
    assert found, message
    return float(found.group(1))


@needs_real
@pytest.mark.slow
@pytest.mark.parametrize(("photo", "size"), [(CHESSBOARD, (640, 480)), (COLOUR_CHART, (1734, 1156))])
@pytest.mark.parametrize("render_check", [False, True])
def test_a_real_photo_without_the_box_is_refused(tmp_path: Path, capsys, photo: Path, size: tuple[int, int],
                                                  render_check: bool) -> None:
    from workbench.cli import main

    intrinsics = scene_lens_intrinsics(tmp_path / "intrinsics.json", *size)
    out = tmp_path / "pose"
    argv = ["calibrate", "pose", str(photo), "--scene", "cornell_cd", "--intrinsics", str(intrinsics), "--out", str(out),
            "--quiet"] + ([] if render_check else ["--no-render-check"])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {photo}: the scene's edges are not in the photo"), err
    assert _coverage(err[0]) < MIN_COVERAGE
    assert not out.exists()  # refused before anything is written (or rendered)


@needs_real
@pytest.mark.slow
def test_free_intrinsics_do_not_rescue_a_chessboard(tmp_path: Path) -> None:
    """The worst case measured: with the focal length and principal point free the fit lays more scene edges
    on the board's lines (0.62 on right01), still below MIN_COVERAGE."""
    with pytest.raises(UserInputError) as info:
        calibrate_pose(CHESSBOARD, "cornell_cd", tmp_path / "pose", settings=PoseSettings(render_check=False),
                       progress=False)
    assert info.value.file == str(CHESSBOARD) and _coverage(str(info.value)) < MIN_COVERAGE
