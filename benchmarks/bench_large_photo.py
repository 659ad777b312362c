"""Benchmark: the report of a 24-megapixel photo (issue 27, item 6; ``make bench``).

`workbench synth cornell_cd --preset large` (one 6000 x 4000 view at 2 spp), a render with
the dataset's truth camera at 2 spp (benchmarks.bench_report.render, as synth renders), and
`workbench report` on view0.dng. Printed against the issue's bars: report.html under 25 MB,
and in Debian's chromium (Playwright) the first paint, from navigation until every tile of
the fitted view is decoded and drawn (reports.page.html's ``reportViewer.settled()``), under 3 s
on the bars' machine, judged as a ratio to the reference workload timed in the same run
(benchmarks/reference_speed.py); then 1:1 at the centre, time until drawn, and no console
error or request other than file: and data:. The report's build time is printed too (no bar).
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

from benchmarks.bench_report import render, write_exr
from benchmarks.reference_speed import SpeedBar, reference_seconds

SCENE = "cornell_cd"
PHOTO = "view0.dng"
SPP = 2
PAGE_BAR_MB = 25.0
FIRST_PAINT = SpeedBar("first paint (fitted view drawn)", 3.0)
SETTLED = "window.reportViewer && window.reportViewer.settled()"


def build(work: Path) -> tuple[Path, dict]:
    """The dataset, the truth-camera render and the report in ``work`` (a dataset or render already there is reused)."""
    from datasets_synthetic.synth import synth
    from reports.report import Inputs, build_report

    dataset = work / "dataset"
    if not (dataset / "truth.json").exists():
        started = time.perf_counter()
        synth(SCENE, dataset, seed=0, preset="large", progress=True)
        print(f"synth --preset large: {time.perf_counter() - started:.0f} s", flush=True)
    render_path = work / f"render{SPP}.exr"
    if not render_path.exists():
        started = time.perf_counter()
        write_exr(render(dataset, SPP, scene=SCENE, photo=PHOTO), render_path)
        print(f"truth-camera render at {SPP} spp: {time.perf_counter() - started:.0f} s", flush=True)
    report = build_report(Inputs(dataset / "photos" / PHOTO, render_path, dataset / "truth.json", SCENE, work / "report"))
    return work / "report" / "report.html", report


def open_in_chromium(page_path: Path) -> dict:
    """Seconds to the fitted view drawn and to 1:1 drawn, console errors and foreign requests."""
    from tests.browser import chromium_page, wait_until

    with chromium_page(page_path, {"width": 1280, "height": 1000}) as (view, errors, requests):
        wait_until(view, SETTLED, timeout_s=120)
        first_paint = view.evaluate("window.reportViewer.drawnAt") / 1000  # since navigation began
        clicked = view.evaluate("performance.now()")
        view.click("#zoom-reset")
        wait_until(view, SETTLED, timeout_s=120)
        one_to_one = (view.evaluate("window.reportViewer.drawnAt") - clicked) / 1000
        zoom = view.evaluate("window.reportState.zoom")
        view.screenshot(path=str(page_path.with_name("report_1to1.png")))
        foreign = [u for u in requests if not u.startswith(("file://", "data:"))]
        return {"first_paint_s": first_paint, "one_to_one_s": one_to_one, "zoom": zoom, "errors": list(errors),
                "foreign_requests": foreign}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, help="keep the dataset, render and report here (reused when there)")
    args = parser.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="bench_large_photo-"))
    try:
        page_path, report = build(work)
        megabytes = page_path.stat().st_size / 1e6
        tiles = report["display"]["tiles"]
        levels = ", ".join(f"{lv['width']}x{lv['height']} {lv['codec']}" for lv in tiles["levels"])
        print(f"report of a {report['size'][0]} x {report['size'][1]} photo built in {report['seconds']:.0f} s; "
              f"levels {levels}; JPEG quality {tiles['jpeg_quality']}")
        print(f"report.html: {megabytes:.1f} MB (bar {PAGE_BAR_MB:g} MB) {'met' if megabytes < PAGE_BAR_MB else 'MISS'}")
        opened = open_in_chromium(page_path)
        print(FIRST_PAINT.judge(opened["first_paint_s"], reference_seconds()))
        print(f"1:1 (zoom {opened['zoom']:g}) drawn in {opened['one_to_one_s']:.2f} s; console errors "
              f"{len(opened['errors'])}, requests other than file: and data: {len(opened['foreign_requests'])}"
              f"{'' if not opened['errors'] and not opened['foreign_requests'] else ' MISS ' + json.dumps(opened)}")
    finally:
        if args.work is None:
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"bench_large_photo: {time.perf_counter() - start:.0f} s")
