"""reports/page/tiles.py: the pyramid a page embeds, and that Chromium draws it back.

* The log code's round trip is within half a code step (its stated precision).
* Each level's box average keeps the image's mean light (what a coarse level must show).
* The exact overview decodes to float16 of the image; the lossy tiles fit the budget they were given.
* In Chromium, a photo large enough for three levels: fitted, then at 1:1, the canvas shows
  the image as the page's own tone curve would draw it, within the lossy code's error.
"""

import base64
import io
import zlib

import numpy as np
import pytest
from PIL import Image

from reports.page import html as page
from reports.page import tiles as image_tiles
from tests.browser import chromium_page, wait_until


def _scene(height: int, width: int, seed: int = 0) -> np.ndarray:
    """A smooth gradient with colour stripes one pixel wide and 2 % noise: what a photo of fringes holds."""
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    image = np.stack([0.05 + 0.5 * u / width, 0.05 + 0.4 * v / height, 0.2 + 0.1 * np.sin(u / 7.0)], axis=2)
    image[:, ::9, 0] *= 2.0
    return (image * (1 + 0.02 * rng.standard_normal(image.shape))).astype(np.float32)


def test_the_log_code_round_trip_is_within_half_a_step():
    image = _scene(64, 96)
    code = image_tiles.LogCode.spanning([image])
    step = (code.hi - code.lo) / 254
    decoded = code.decode(code.encode(image))
    inside = image >= 2.0 ** code.lo  # below the range every value reads as its floor or black
    assert np.all(np.abs(np.log2(decoded[inside] / image[inside])) <= step / 2 + 1e-6)
    assert code.decode(code.encode(np.zeros((2, 2, 3))))[0, 0, 0] == 0  # black stays black


def test_each_level_keeps_the_mean_light():
    image = _scene(301, 517)  # odd sizes: the last row and column are averaged with themselves
    half = image_tiles.halved(image)
    assert half.shape == (151, 259, 3)
    # float32 sums of 155 k values: the means agree to 1e-5 relative; the padded edge adds one row and column
    assert np.allclose(half[:-1, :-1].mean(axis=(0, 1)), image[:300, :516].mean(axis=(0, 1)), rtol=1e-5)


def test_the_overview_is_exact_and_the_fine_levels_fit_their_budget():
    image = _scene(1100, 1500)  # 1.65 MP: levels 1500, 750 (0.41 MP, the exact overview)
    images = {"photo": image, "render": image * 1.1}
    best = image_tiles.pyramid(images, budget=10**9)
    assert [(lv["width"], lv["height"], lv["codec"]) for lv in best["levels"]] == [
        (1500, 1100, "log8-jpeg"), (750, 550, "float16-shuffled-deflate")]
    assert [len(best["tiles"]["photo"][k]) for k in range(2)] == [3 * 3, 2 * 2]
    shuffled = zlib.decompress(base64.b64decode(best["tiles"]["photo"][1][0]))
    first = np.frombuffer(shuffled, np.uint8).reshape(2, -1).T.copy().view("<f2").reshape(512, 512, 3)
    assert np.array_equal(first, image_tiles.halved(image)[:512, :512].astype(np.float16))
    tile = Image.open(io.BytesIO(base64.b64decode(best["tiles"]["photo"][0][0])))
    assert tile.format == "JPEG" and tile.size == (512, 512) and tile.mode == "RGB"
    assert best["jpeg_quality"] == image_tiles.JPEG_QUALITIES[0]

    def characters(pyramid, levels):
        return sum(len(t) for name in pyramid["tiles"] for k in levels for t in pyramid["tiles"][name][k])

    budget = characters(best, [1]) + characters(best, [0]) // 3  # a third of what the best quality takes
    tight = image_tiles.pyramid(images, budget=budget)
    # the estimate samples a few tiles; 10 % over is the most measured on this image at any quality
    assert tight["jpeg_quality"] < best["jpeg_quality"] and characters(tight, [0, 1]) <= 1.1 * budget


@pytest.mark.slow
def test_chromium_draws_every_level_of_a_large_photo(tmp_path):
    height, width = 1100, 1500
    photo = _scene(height, width)
    pyramid = image_tiles.pyramid({"photo": photo, "render": photo * 0.5})
    path = tmp_path / "report.html"
    path.write_text(page.render_page(title="large", pyramid=pyramid, exposure_ev=0.0, maps={}, sections=[],
                                     notes=[], errors=[]))
    with chromium_page(path, {"width": 1100, "height": 900}) as (view, errors, requests):
        wait_until(view, "window.reportViewer.settled()")
        fit = view.evaluate("window.reportState.zoom")
        assert fit == pytest.approx(min(page.MAX_VIEW[0] / width, page.MAX_VIEW[1] / height))
        view.click("#zoom-reset")
        wait_until(view, "window.reportViewer.settled()")
        state = view.evaluate("({zoom: reportState.zoom, x: reportState.x, y: reportState.y})")
        assert state["zoom"] == 1
        w, h = view.evaluate("[document.getElementById('ab-canvas').width, document.getElementById('ab-canvas').height]")
        shown = np.array(view.evaluate(f"Array.from(document.getElementById('ab-canvas').getContext('2d')"
                                       f".getImageData(0, 0, {w}, {h}).data)"), dtype=float).reshape(h, w, 4)[..., :3]
        x0, y0 = round(-state["x"]), round(-state["y"])
        expected = 255 * _srgb(photo[y0:y0 + h, x0:x0 + w])
        # the log code's 2.2 % step and JPEG at the chosen quality: 8-bit levels, median and 99th percentile
        error = np.abs(shown - expected)
        assert np.median(error) <= 2.0 and np.percentile(error, 99) <= 12.0, (np.median(error), np.percentile(error, 99))
        assert view.evaluate("window.reportViewer.draws") >= 2
        assert not errors, errors
        assert all(url.startswith(("file://", "data:")) for url in requests), requests


def _srgb(linear: np.ndarray) -> np.ndarray:
    v = np.clip(linear, 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
