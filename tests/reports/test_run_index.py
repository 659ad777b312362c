"""A verify run's index page (reports/page/run_index.py); the page on a real run's files is tested in
tests/workbench/test_verify.py (in Chromium)."""

import numpy as np
from PIL import Image

from reports.page.run_index import THUMBNAIL_WIDTH, index_html, photo_rows, thumbnail_png


def test_thumbnail_is_the_srgb_encoding_at_the_index_width(tmp_path):
    linear = np.full((48, 64, 3), 0.09, np.float32)  # times exposure 2: 0.18, mid grey
    thumbnail_png(linear, 2.0, tmp_path / "thumbnail.png")
    image = np.asarray(Image.open(tmp_path / "thumbnail.png"))
    assert image.shape == (THUMBNAIL_WIDTH * 48 // 64, THUMBNAIL_WIDTH, 3)
    # IEC 61966-2-1: 1.055 * 0.18^(1/2.4) - 0.055 = 0.4614 -> 117.7 of 255; Lanczos keeps a flat field flat
    assert np.all(image == 118)


def test_text_from_the_run_is_escaped(tmp_path):
    record = {"identity": {"dataset": "/data/<b>d</b>", "scene": "<script>alert(1)</script>"},
              "status": "finished", "seconds": 1.0, "settings": {"preset": "<i>draft</i>"}, "versions": {},
              "stages": {"report": {"status": "done", "seconds": 1.0, "result": {"reports": {}}}},
              "summary": {"notes": ["a note <img src=x onerror=alert(2)>"]}}
    text = index_html(tmp_path, record)
    for raw in ("<script>alert", "<b>d</b>", "<i>draft", "<img src=x"):
        assert raw not in text, raw
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "no scene fit in this run" in text  # no RUN/fit/scene_fit.json


def test_links_to_reports_of_oddly_named_photos_are_url_encoded(tmp_path):
    """A photo named ``a#1%41?x.dng``: ``#`` would cut the link at a fragment, ``?`` at a query and
    ``%41`` would decode to ``A`` (issue 46, cause 10); each is percent-encoded, then HTML-escaped."""
    import re
    from urllib.parse import unquote

    name = "a#1%41?x.dng"
    folder = tmp_path / "report" / "a#1%41?x"
    folder.mkdir(parents=True)
    (folder / "report.json").write_text("{}")
    record = {"stages": {"report": {"result": {"reports": {name: {"html": "a#1%41?x/report.html"}}}}}}
    link = re.search(r"href='([^']*)'", photo_rows(tmp_path, record)).group(1)
    assert link == "report/a%231%2541%3Fx/report.html"
    assert (tmp_path / unquote(link)).parent == folder  # the browser's decoding finds the folder
