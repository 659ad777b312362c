"""reports/page/html.py in a real browser: Debian's chromium driven by Playwright.

The page is built from small images (no render needed: the page does not care where its
pixels came from), loaded from file://, and used as a person would: A/B flip by button
and key, wheel zoom and drag on one panel, the exposure slider. Chromium comes from the
Makefile's install rule (Playwright's own browser download is not available here).
"""

import numpy as np
import pytest

from reports.page import html as page
from reports.page import tiles as image_tiles
from tests.browser import chromium_page, wait_until

WIDTH, HEIGHT = 96, 72
PIXEL_CHANGE = 8  # 8-bit levels: a flip or an exposure step must change the canvas by more than this somewhere
SCREENSHOT = "report_page.png"


def _page_html(tmp_path, title="scene <script>alert(1)</script>"):
    rng = np.random.default_rng(0)
    photo = rng.uniform(0.05, 0.5, (HEIGHT, WIDTH, 3)).astype(np.float32)
    render = photo.copy()
    render[:, : WIDTH // 2] *= 2.0  # the left half differs: the flip must show it
    error = np.abs(photo - render).mean(axis=2)
    maps = {"relative error": {"uri": page.png_data_uri(page.false_colour(error, 1.0)), "legend": "0 to 1"},
            "<b>bold</b>": {"uri": page.png_data_uri(page.false_colour(error, 0.5)), "legend": "0 to 0.5"}}
    sections = [("a table <script>", page.table([{"name": "<script>alert(2)</script>", "value": 1.5}]))]
    text = page.render_page(title=title, pyramid=image_tiles.pyramid({"photo": photo, "render": render}),
                            exposure_ev=0.0, maps=maps, sections=sections, notes=["note <img src=x onerror=alert(3)>"],
                            errors=[])
    path = tmp_path / "report.html"
    path.write_text(text)
    return path


def test_text_from_files_is_escaped(tmp_path):
    text = _page_html(tmp_path).read_text()
    assert "<script>alert" not in text
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "<img src=x" not in text
    assert "<b>bold</b>" not in text


@pytest.mark.slow
def test_page_in_chromium(tmp_path):
    path = _page_html(tmp_path)
    with chromium_page(path, {"width": 900, "height": 700}) as (view, console_errors, requests):

        assert not console_errors, console_errors
        assert all(url.startswith(("file://", "data:")) for url in requests), requests
        # every image decodes
        broken = view.evaluate("Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).length")
        assert broken == 0
        assert view.evaluate("document.images.length") >= 3
        # the title with <script> in it shows as text
        assert "<script>alert(1)</script>" in view.inner_text("h1")

        def pixels():
            wait_until(view, "window.reportViewer.settled()")
            return np.array(view.evaluate(
                "Array.from(document.getElementById('ab-canvas').getContext('2d')"
                f".getImageData(0, 0, {WIDTH}, {HEIGHT}).data)"), dtype=int).reshape(HEIGHT, WIDTH, 4)

        photo = pixels()
        assert view.inner_text("#ab-label") == "photo"
        view.click("#flip")
        render = pixels()
        assert view.inner_text("#ab-label") == "render"
        assert np.abs(render - photo)[:, : WIDTH // 2, :3].max() > PIXEL_CHANGE  # the left half differs
        assert np.abs(render - photo)[:, WIDTH // 2 + 1:, :3].max() <= 1  # the right half is the same image
        view.keyboard.press("f")
        assert view.inner_text("#ab-label") == "photo"
        assert np.array_equal(pixels(), photo)

        # zoom on the first panel; both panels follow
        first = view.locator(".viewport").first
        box = first.bounding_box()
        view.mouse.move(box["x"] + 30, box["y"] + 20)
        view.mouse.wheel(0, -200)
        view.wait_for_timeout(100)
        transforms = view.evaluate("Array.from(document.querySelectorAll('.stage')).map(s => s.style.transform)")
        assert len(transforms) == 2 and transforms[0] == transforms[1] and "scale(1.25)" in transforms[0]
        view.mouse.down()
        view.mouse.move(box["x"] + 50, box["y"] + 40)
        view.mouse.up()
        panned = view.evaluate("Array.from(document.querySelectorAll('.stage')).map(s => s.style.transform)")
        assert panned[0] == panned[1] and panned[0] != transforms[0]

        # the exposure slider acts on the linear data
        before = pixels()
        view.evaluate("const s = document.getElementById('exposure'); s.value = '1.5';"
                      "s.dispatchEvent(new Event('input'))")
        after = pixels()
        assert (after[..., :3] >= before[..., :3]).all() and (after[..., :3] - before[..., :3]).max() > PIXEL_CHANGE

        # the error-map choice changes the map shown
        first_map = view.get_attribute("#map-img", "src")
        view.select_option("#map-select", index=1)
        assert view.get_attribute("#map-img", "src") != first_map
        view.screenshot(path=str(tmp_path / SCREENSHOT), full_page=True)
        assert not console_errors, console_errors
    assert (tmp_path / SCREENSHOT).stat().st_size > 1000


def test_values_print_as_a_person_reads_them():
    """reports.page.html.format_value: 4 significant figures, lists of numbers joined, dicts as tables,
    None as '-', text escaped; never a Python repr."""
    assert page.format_value(0.13352388710915497) == "0.1335"
    assert page.format_value([306.3776550292969, 277.96197509765625]) == "306.4, 278"
    assert page.format_value(None) == "-" and page.format_value(float("nan")) == "-"
    assert page.format_value(np.float32(2.5)) == "2.5" and page.format_value(np.int64(7)) == "7"
    nested = page.format_value({"center": (306.3776550292969, 277.96), "counts": {"ok": 250, "<b>": 1}})
    assert "{" not in nested and "(" not in nested and "<b>" not in nested
    assert "<th>center</th><td>306.4, 278</td>" in nested and "&lt;b&gt;" in nested
