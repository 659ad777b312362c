"""A verify run's index page (RUN/index.html): what the run concluded, one row per photo.

First the scene fit's verdict (reports.page.verdict_block, the block each report opens with);
then a table with one row per photo: a thumbnail linking to that photo's report, the
report's verdict, the calibration's pose residual, the photo-vs-render band-edge offsets
(median, 95th percentile, count) and the report's problems; the accuracy-versus-time
figures of the run's ``--study`` folders (reports.page.study_figures); then the stages (time, or
skipped as unchanged), the run's settings and versions. Self-contained like the reports:
the thumbnails are data: URIs (each report writes ``thumbnail.png`` beside report.json),
the links relative paths inside RUN, and every text from a file goes through html.escape
(reports.page.html).
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from PIL import Image

from reports.page import html as page
from reports.page.study_figures import study_sections
from reports.page.verdict_block import verdict_html
from workbench.core.files import atomic_write_text

THUMBNAIL_WIDTH = 240  # px: the index's rows; the report holds the full image
INDEX_STYLE = ("td.photo, #photos th:first-child { text-align: left; } td.photo img { display: block; width: 240px; }"
               " td.left { text-align: left; }")


def thumbnail_png(linear_srgb: np.ndarray, exposure: float, path: Path, width: int = THUMBNAIL_WIDTH) -> None:
    """``linear_srgb`` (H, W, 3) times ``exposure`` through the sRGB curve (IEC 61966-2-1), 8-bit,
    resized to ``width`` px across (Lanczos), written as a PNG at ``path`` (atomically)."""
    x = np.clip(np.nan_to_num(linear_srgb * exposure, nan=0.0), 0.0, 1.0)
    encoded = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    image = Image.fromarray((encoded * 255 + 0.5).astype(np.uint8))
    height = max(1, round(image.height * width / image.width))
    partial = path.with_name(path.name + ".partial")
    image.resize((width, height), Image.Resampling.LANCZOS).save(partial, format="PNG", optimize=True)
    partial.replace(path)


def _offsets(fo: dict | None) -> tuple[str, str, str]:
    if not fo or fo.get("median") is None:
        return "-", "-", "0"
    return f"{fo['median']:.2f}", f"{fo['p95']:.2f}", str(fo.get("count", "-"))


def href(link: str) -> str:
    """A relative file link for an href attribute: each character a URL gives a meaning (``#``, ``?``,
    ``%``, spaces) percent-encoded [RFC 3986, Sec. 2.1], then HTML-escaped, so a photo named
    ``a#1%41?x.dng`` links to its own folder."""
    return html.escape(quote(link, safe="/"))


def _thumbnail_cell(folder: Path, link: str, name: str) -> str:
    thumb = folder / "thumbnail.png"
    label = html.escape(name)
    if not thumb.is_file():
        return f"<td class='photo'><a href='{href(link)}'>{label}</a> (no thumbnail)</td>"
    uri = "data:image/png;base64," + base64.b64encode(thumb.read_bytes()).decode("ascii")
    return f"<td class='photo'><a href='{href(link)}'><img src='{uri}' alt='{label}'>{label}</a></td>"


def photo_rows(root: Path, record: dict[str, Any]) -> str:
    """The photos' table: one row per report of the run's report stage."""
    reports = record["stages"]["report"]["result"]["reports"]
    residuals = record.get("summary", {}).get("photos", {})
    head = ["photo (its report)", "verdict", "pose residual RMS (px)", "band-edge offset median (px)",
            "p95 (px)", "edges", "problems"]
    rows = []
    for name, entry in reports.items():
        folder = root / "report" / Path(entry["html"]).parent
        report = json.loads((folder / "report.json").read_text())
        pose = residuals.get(name, {}).get("pose_rms_px")
        median, p95, count = _offsets(report.get("fringe_offset_px"))
        problems = report.get("problems", [])
        cells = [html.escape(str((report.get("verdict") or {}).get("verdict", "no scene fit"))),
                 "-" if pose is None else f"{pose:.3f}", median, p95, count]
        rows.append("<tr>" + _thumbnail_cell(folder, f"report/{entry['html']}", name)
                    + "".join(f"<td>{c}</td>" for c in cells)
                    + f"<td class='left'>{html.escape('; '.join(problems)) if problems else 'none'}</td></tr>")
    return ("<table id='photos'><thead><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head)
            + "</tr></thead><tbody>" + "".join(rows) + "</tbody></table>")


def _stages(record: dict[str, Any]) -> str:
    rows = [{"stage": name, "status": "skipped (unchanged)" if stage.get("skipped") else stage.get("status", "-"),
             "seconds": float(stage.get("seconds", float("nan")))} for name, stage in record["stages"].items()]
    return page.table(rows)


def _studies(record: dict[str, Any]) -> str:
    """The accuracy-versus-time figures of the run's `--study` folders (none: nothing)."""
    folders = tuple(Path(folder) for folder in record.get("settings", {}).get("studies", []))
    return "".join(f"<h2>{html.escape(heading)}</h2>{figure}" for heading, figure in study_sections(folders))


def index_html(root: Path, record: dict[str, Any]) -> str:
    """The page's HTML for the run in ``root`` whose run.json content is ``record``."""
    fit_file = root / "fit" / "scene_fit.json"
    fitted = json.loads(fit_file.read_text()) if fit_file.is_file() else None
    verdict = verdict_html(fitted["verdict"] | {"bias_correction": fitted.get("bias_correction")}) if fitted else (
        "<div class='note'>no scene fit in this run (fit/not_fitted.txt says why, where it ran)</div>")
    identity = record.get("identity", {})
    dataset = Path(str(identity.get("dataset", "")))
    title = f"verify run: {Path(str(identity.get('scene', ''))).name} on {dataset.parent.name}/{dataset.name}"
    seconds = record.get("seconds")
    status = f"{record.get('status', '-')}" + (f" in {seconds:.1f} s" if isinstance(seconds, (int, float)) else "")
    notes = "".join(f"<div class='note'>{html.escape(n)}</div>" for n in record.get("summary", {}).get("notes", []))
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="default-src 'none'; img-src data:; style-src 'unsafe-inline'">
<title>{html.escape(title)}</title><style>{page.STYLE}{INDEX_STYLE}</style></head>
<body>
<h1>{html.escape(title)}</h1>
<p>run {html.escape(status)}; dataset {html.escape(str(identity.get('dataset', '')))},
scene {html.escape(str(identity.get('scene', '')))}</p>
{verdict}{notes}
<h2>photos</h2>{photo_rows(root, record)}
{_studies(record)}
<h2>stages</h2>{_stages(record)}
<h2>settings</h2>{page.key_values(record.get('settings', {}))}
<h2>versions</h2>{page.key_values(record.get('versions', {}))}
</body></html>
"""


def write_run_index(root: Path, record: dict[str, Any]) -> Path:
    """RUN/index.html for the finished run (written atomically); its path."""
    path = root / "index.html"
    atomic_write_text(path, index_html(root, record))
    return path
