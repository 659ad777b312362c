"""The lens's uncertainty maps on the report page (reports/page/lens_maps.py; issue 26 item 2: "the
projection uncertainty map and the cross-validation diff on the real views, in the report").

* Real views (BoofCV-Data's Bumblebee2, 11 views): `workbench calibrate intrinsics` writes the two
  16-bit PNGs beside intrinsics.json; the report's reader finds them through a calibration.json
  in the same folder, reads the values intrinsics.json's grid holds (to the PNG's rounding), and
  the page's figure embeds them as one PNG image; without the PNGs the grid values are drawn.
* A calibration with no intrinsics.json beside it gets one line saying so.
* A verify-style run on the shared synthetic dataset (`calibrate DATASET`, whose folder keeps
  intrinsics.json with the grids but no PNGs, then `workbench report`): report.html holds the
  figure, next to the summary's lens row, with the CD outlined, and chromium shows it.
"""

from __future__ import annotations

import base64
import io
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from calibration.intrinsics.projection_uncertainty import PNG_SCALE
from reports.page import lens_maps
from tests.browser import chromium_page
from tests.calibration.test_pose import calibrated_dataset
from tests.conftest import synthetic_dataset
from workbench.cli import main

REAL = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real" / "chessboard_bumblebee2_left"
VIEWS = sorted(REAL.glob("left*.jpg"))
needs_bumblebee = pytest.mark.skipif(len(VIEWS) != 11, reason=f"BoofCV-Data's Bumblebee2 views not found in {REAL}")
ROUNDING_PX = 0.5 / PNG_SCALE   # a 16-bit map's rounding (1 = 0.001 px)
PHOTO = "view0.dng"             # a photo calibrate DATASET fitted a pose to
RENDER_SPP = 16                 # the page is what is tested, not the comparison: a noisy render will do


def _figure_image(text: str) -> Image.Image:
    start = text.index("src='data:image/png;base64,") + len("src='data:image/png;base64,")
    return Image.open(io.BytesIO(base64.b64decode(text[start:text.index("'", start)])))


@pytest.fixture(scope="module")
def bumblebee(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bumblebee") / "intrinsics.json"
    assert main(["calibrate", "intrinsics", *map(str, VIEWS), "--board", "4x6", "--square-mm", "30", "--out", str(out),
                 "--quiet"]) == 0
    (out.parent / "calibration.json").write_text("{}")   # a report's --calibration file beside it
    return out


@needs_bumblebee
def test_the_real_views_maps_reach_the_figure(bumblebee: Path):
    record = json.loads(bumblebee.read_text())
    maps = lens_maps.read_maps(bumblebee.with_name("calibration.json"))
    assert not isinstance(maps, str), maps
    assert [m.source.split(" ")[0] for m in maps] == [record["projection_uncertainty"]["image"],
                                                     record["cross_validation"]["image"]]
    for m, grid in zip(maps, (record["projection_uncertainty"]["map_px"]["std"],
                              record["cross_validation"]["map_px"]["diff"]), strict=True):
        expected = np.where(np.asarray(grid) < 0, np.nan, grid)
        assert m.values_px.shape == expected.shape == (len(m.vs), len(m.us))
        np.testing.assert_allclose(m.values_px, expected, atol=ROUNDING_PX + 1e-9)   # the PNG is the grid, rounded
        assert m.us[-1] == record["width"] - 1 and m.vs[-1] == record["height"] - 1
    html_text = lens_maps.figure_html(bumblebee.with_name("calibration.json"))
    assert html_text.startswith("<figure id='lens-maps'>") and "projection uncertainty" in html_text
    image = _figure_image(html_text)
    assert image.width > 1.8 * image.height        # two panels side by side, each with its colour bar
    median = record["cross_validation"]["diff_px"]["median"]
    assert f"median {median:.3g} px against" in html_text   # the caption states the diff beside its prediction


@needs_bumblebee
def test_without_the_pngs_the_grid_values_are_drawn(bumblebee: Path, tmp_path: Path):
    copy = tmp_path / "intrinsics.json"
    copy.write_text(bumblebee.read_text())   # the record alone: its PNGs are not beside the copy
    maps = lens_maps.read_maps(copy)
    assert not isinstance(maps, str) and all("grid values" in m.source for m in maps)
    from_png = lens_maps.read_maps(bumblebee)
    assert not isinstance(from_png, str)
    for grid, png in zip(maps, from_png, strict=True):
        np.testing.assert_allclose(grid.values_px, png.values_px, atol=ROUNDING_PX + 1e-9)


def test_a_calibration_without_intrinsics_says_so_in_one_line(tmp_path: Path):
    calibration = tmp_path / "truth.json"
    calibration.write_text(json.dumps({"camera": {}}))
    text = lens_maps.figure_html(calibration)
    assert text.startswith("<p id='lens-maps'") and "no intrinsics.json beside it" in text and "\n" not in text
    (tmp_path / "intrinsics.json").write_text(json.dumps({"width": 640, "height": 480}))
    assert "holds no projection uncertainty" in lens_maps.figure_html(calibration)
    (tmp_path / "intrinsics.json").write_text(json.dumps({"projection_uncertainty": {"map_px": {"std": "x"}}}))
    assert "is malformed (KeyError" in lens_maps.figure_html(calibration)   # the report goes on without the figure


@pytest.mark.slow
def test_a_verify_style_report_page_holds_the_maps(tmp_path_factory, tmp_path: Path):
    # calibrate DATASET (shared per session) then workbench report with its calibration.json, as verify runs them
    import OpenImageIO as oiio

    from calibration.calibration_file import read_camera
    from tests.reports.test_report_synthetic import SCENE, _render_image

    out, calibration, _ = calibrated_dataset(tmp_path_factory)
    dataset = synthetic_dataset(tmp_path_factory, 0)
    image = _render_image(read_camera(dataset / "truth.json", PHOTO).model, spp=RENDER_SPP)
    render = tmp_path / "render.exr"
    writer = oiio.ImageOutput.create(str(render))
    assert writer is not None and writer.open(str(render), oiio.ImageSpec(image.shape[1], image.shape[0], 3, oiio.FLOAT))
    writer.write_image(image)
    writer.close()
    report = tmp_path / "report"
    assert main(["report", "--photo", str(dataset / "photos" / PHOTO), "--render", str(render), "--calibration",
                 str(out / "calibration.json"), "--scene", SCENE, "--out", str(report)]) == 0
    page = (report / "report.html").read_text()
    summary = page[page.index("<section id='summary'>"):]
    summary = summary[:summary.index("</section>")]
    assert "lens model and its uncertainty" in summary and "<figure id='lens-maps'>" in summary
    assert "grid values" in summary and "the CD outlined in white" in summary   # calibrate DATASET writes no PNGs
    assert calibration["intrinsics"]["cross_validation"]["diff_median_px"] > 0
    # the chosen distortion terms reach the digest (the draft boards' real tangential terms: k1, k2, p1, p2)
    assert calibration["intrinsics"]["distortion_terms"][:2] == ["k1", "k2"], calibration["intrinsics"]
    assert _figure_image(summary).width > 1.8 * _figure_image(summary).height   # both maps drawn
    with chromium_page(report / "report.html", {"width": 1400, "height": 1000}) as (view, errors, requests):
        shown = view.evaluate("document.querySelector('#summary #lens-maps img').naturalWidth")
        assert shown > 0 and not errors, errors   # the browser decodes it (the page's policy allows data: images)
        assert all(url.startswith(("file:", "data:")) for url in requests)
