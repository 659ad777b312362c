"""``workbench verify`` and ``workbench score`` (workbench/verify.py, workbench/score.py).

One reference run on the shared synthetic dataset (seed 0, draft, 640 x 480) at a few
samples per pixel; a run killed (SIGKILL) during calibration and again during rendering,
then resumed, must end with the reference's calibration (to round-off), keep the render
the killed run finished (equal to a fresh render of its fitted scene) and render the
rest; a re-run skips every stage; score compares the run with the truth; bad input is
refused before anything runs.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from reports.page import html as page
from tests import calibration_bounds as bounds
from tests import realisation_bounds
from tests.conftest import synthetic_dataset
from workbench.cli import main
from workbench.verify import STAGES, VerifySettings, open_run, verify

SPP = 4  # the render stage at 4 spp: one pass per photo, a few seconds; the report only needs the pixels to exist
# A re-run only hashes the inputs (17 MB of dataset files) and reads the scene: every stage is skipped (asserted from
# run.json, not from the clock: issue 23).
# The resumed calibration equals the uninterrupted run's up to round-off, which the fit amplifies: OpenCV's
# parallel sums move the intrinsics by ~1e-9 relative (1.4e-9 measured on dist[0]; tests/calibration saw 4.7e-9)
# and the fit renders' film sums float32 samples in thread order, so two uninterrupted runs' pose fits end apart
# by ~1e-4 deg and ~1e-3 mm (measured: 8.6e-5 deg, 1.0e-3 mm on view1). Bars: 1e-3 deg and 1e-2 mm (the
# calibration's own errors are 0.004-0.06 deg and 0.25-0.62 mm), intrinsics 1e-6 relative, exposure scale 1e-3
# relative (its accuracy is 0.3 %), the pose residuals' RMS 1e-3 px.
SAME_ROTATION_DEG, SAME_CENTRE_MM, SAME_INTRINSICS, SAME_EXPOSURE, SAME_RESIDUAL_PX = 1e-3, 1e-2, 1e-6, 1e-3, 1e-3
# A render kept from the killed run equals a fresh render of the same fitted scene (same scene text, same seed: the
# same samples), up to the order the film sums each pixel's 4 float32 samples in: a few ulps (1.2e-7 each).
PIXELS_RELATIVE = 1e-5
KILL_POLL_S = 0.2
KILL_TIMEOUT_S = 600.0
# score's errors within the bounds over render realisations (tests/calibration_bounds.py; issue 14's 0.1 deg and
# 1 mm, missed by 1 realisation in 6, are judged in benchmarks/bench_calibration.py).
ROTATION_BAR_DEG, CENTRE_BAR_MM = bounds.ROTATION_DEG, bounds.CENTRE_MM


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return synthetic_dataset(tmp_path_factory, 0)


@pytest.fixture(scope="module")
def reference(dataset: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, float]:
    out = tmp_path_factory.mktemp("verify") / "run"
    start = time.perf_counter()
    record = verify(dataset, "cornell_cd", out, VerifySettings(spp=SPP, progress=False))
    return out, record, time.perf_counter() - start


@pytest.mark.slow
def test_verify_ends_with_a_report_and_run_json(reference: tuple[Path, dict, float]) -> None:
    out, record, _ = reference
    saved = json.loads((out / "run.json").read_text())
    assert saved["status"] == "finished" and list(saved["stages"]) == list(STAGES)
    for name, stage in saved["stages"].items():
        assert stage["status"] == "done" and len(stage["key"]) == 64, name
        assert stage["seconds"] >= 0 and "estimate_s" in stage, name
        assert (out / name / ".stage-key").read_text() == stage["key"], name
    assert saved["settings"]["render_spp"] == SPP and saved["versions"]["workbench"]
    assert not (out / ".staging").exists()
    photos = saved["summary"]["photos"]
    assert sorted(photos) == ["view0.dng", "view1.dng"]
    for p in photos.values():
        assert Path(p["report"]).is_file() and p["report"].endswith("report.html")
        assert set(p["fringe_offset_px"]) >= {"median", "p95", "count"}
        assert 0 < p["pose_rms_px"] < 1.0  # calibration's residual: sub-pixel on a synthetic dataset
    inputs = [name for stage in saved["stages"].values() for name in stage["inputs"]]
    assert "photos/view0.dng" in inputs and not any("truth" in name for name in inputs)  # verify never reads the truth
    assert "brackets/ev-6.dng" in inputs  # the report fills view0's clipped highlights from its bracket
    sidecar = json.loads((out / "render" / "view0.json").read_text())
    assert Path(sidecar["output"]) == out / "render" / "view0.exr"  # where the render is, not the staging folder
    view0 = json.loads((out / "report" / "view0" / "report.json").read_text())
    assert [Path(u["path"]).name for u in view0["photo_decoding"]["bracket"]][-1] == "ev-6.dng"
    view1 = json.loads((out / "report" / "view1" / "report.json").read_text())
    assert view1["photo_decoding"]["bracket"] == []  # the bracket shows view0: every frame is left out for view1


@pytest.mark.slow
def test_the_fit_stage_fits_an_unperturbed_scene_and_states_its_verdict(reference: tuple[Path, dict, float]) -> None:
    """Issue 25, on a dataset made from the scene file itself (seed 0): the fit stage writes the
    verdict with its test's numbers, the fitted values stay within the spread that other render
    realisations of the dataset show (tests/realisation_bounds.py), the fitted scene loads as a
    scene, the fitted scene is re-rendered exactly when the verdict is ``model``, and each report
    carries the verdict and shows it first on the page.

    Not asserted (issue 23): the verdict ``consistent`` itself. Over 12 render realisations of
    this dataset it was ``consistent`` on 11 (``model`` on one: without the forward model's offsets,
    which 4-spp renders cannot measure, the period's std was a third of its spread there;
    tests/realisation_bounds.py), but its false-alarm rate is the test's alpha
    (1e-3) plus the file-median rule's (2e-3), above the suite's budget; the benchmark
    (benchmarks/bench_realisations.py) measures it."""
    from renderer.scene import load_scene

    out, _, _ = reference
    fit = json.loads((out / "fit" / "scene_fit.json").read_text())
    verdict = fit["verdict"]
    assert verdict["verdict"] in ("consistent", "model", "camera", "unexplained"), verdict
    for test in (verdict["test"]["noise_only"], verdict["test"]["noise_and_camera"]):
        assert test["dof"] == len(fit["components"]) and 0.0 <= test["p_value"] <= 1.0 and test["statistic"] >= 0, test
    moved = np.abs(np.array(fit["values"]) - np.array(fit["nominal_values"]))
    limits = np.array([realisation_bounds.FIT_MOVE[c] for c in fit["components"]])
    assert np.all(moved < limits), dict(zip(fit["components"], (moved / limits).tolist(), strict=True))
    assert set(fit["parameters"]) == {"cd[0].structure.period", "cd[0].normal", "light.center"}  # the defaults
    assert load_scene(out / "fit" / "fitted_scene.toml").name == "cornell_cd"
    assert (out / "rerender" / "view0.exr").exists() == (verdict["verdict"] == "model")
    for photo in ("view0.dng", "view1.dng"):  # 4-spp renders: too noisy to measure the forward model's offsets on
        assert fit["bias_correction"][photo]["used"] is False, fit["bias_correction"]
    for photo in ("view0", "view1"):
        report = json.loads((out / "report" / photo / "report.json").read_text())
        assert report["verdict"]["verdict"] == verdict["verdict"]
        assert report["verdict"]["bias_correction"] == fit["bias_correction"]
        page = (out / "report" / photo / "report.html").read_text()
        assert page.index("<section id='verdict'>") < page.index("<canvas")
        # the page says the offsets were not taken off, and what that leaves out of the stds
        assert "view0.dng: not used (" in page and "can be called otherwise" in page


@pytest.mark.slow
def test_report_pages_print_numbers_to_their_precision(reference: tuple[Path, dict, float]) -> None:
    """Issue 27, item 2, on the pages a real run wrote: no Python repr ({'...}, [[...) and no number
    with more than 6 significant digits in the visible text (scripts and data: URIs left out; the page's
    numbers go through reports.page.html.format_value, 4 significant figures); the summary block sits
    between the verdict and the images with report.json's fringe offsets; the calibration's
    table gives fx with its standard deviation from calibration.json."""
    import html as html_module
    import re

    out, _, _ = reference
    calibration = json.loads((out / "calibration" / "calibration.json").read_text())
    for photo in ("view0", "view1"):
        text = (out / "report" / photo / "report.html").read_text()
        text = re.sub(r"<script.*?</script>", " ", text, flags=re.S)
        visible = html_module.unescape(re.sub(r"<[^>]+>", " ", re.sub(r"data:[^'\"]+", "", text)))
        assert "{'" not in visible and "[[" not in visible, re.search(r".{40}(\{'|\[\[).{40}", visible)
        long = [n for n in re.findall(r"\d+\.\d+", visible) if len(n.replace(".", "").lstrip("0")) > 6]
        assert not long, long[:5]
        report = json.loads((out / "report" / photo / "report.json").read_text())
        fo = report["fringe_offset_px"]
        assert text.index("<section id='verdict'>") < text.index("<section id='summary'>") < text.index("<canvas")
        summary = text[text.index("<section id='summary'>"):text.index("</section>", text.index("<section id='summary'>"))]
        assert f"median {fo['median']:.3g} px, p95 {fo['p95']:.3g} px ({fo['count']} edges)" in summary
        row = re.search(r"<tr><td>fx</td><td>([^<]+)</td><td>([^<]+)</td><td>px</td></tr>", text)
        assert row, "no fx row in the calibration table"
        assert float(row.group(2)) == pytest.approx(calibration["std"]["fx"], rel=1e-3)  # 4 significant figures
        tested = report["region_test"]  # issue 27, item 3: fed by the run's own render variance and calibration
        assert tested["render_noise"] and tested["exposure_rel_std"] > 0 and tested["camera_draws"] > 0
        table = text[text.index("<div id='region-test'>"):]
        for name, entry in tested["regions"].items():
            if "z" in entry:
                assert f"<td>{name}</td>" in table and f"<td>{page.format_number(entry['z'])}</td>" in table


@pytest.mark.slow
def test_the_run_index_links_every_report_in_chromium(reference: tuple[Path, dict, float]) -> None:
    """Issue 27, item 5: RUN/index.html, written by the run itself, opens in Debian's chromium
    without console errors or a request other than file: and data:, shows the scene fit's verdict
    first, one row per photo with a thumbnail whose link opens that photo's report, and the
    numbers of each row equal that report's report.json (formatted to 2 decimals)."""
    from tests.browser import chromium_page

    out, record, _ = reference
    index = out / "index.html"
    assert record["summary"]["index"] == str(index) and index.is_file()
    with chromium_page(index, {"width": 1200, "height": 900}) as (view, errors, requests):
        assert view.evaluate("document.body.firstElementChild.nextElementSibling.nextElementSibling.id") == "verdict"
        rows = view.evaluate("Array.from(document.querySelectorAll('#photos tbody tr')).map(r => ({"
                             "href: r.querySelector('a').getAttribute('href'), "
                             "cells: Array.from(r.querySelectorAll('td')).map(c => c.innerText.trim())}))")
        assert [r["cells"][0] for r in rows] == ["view0.dng", "view1.dng"]
        assert view.evaluate("Array.from(document.querySelectorAll('#photos img'))"
                             ".filter(i => i.complete && i.naturalWidth === 240).length") == 2
        for row in rows:
            report = json.loads((out / Path(row["href"]).parent / "report.json").read_text())
            fo = report["fringe_offset_px"]
            assert row["cells"][1] == report["verdict"]["verdict"]
            assert row["cells"][3:6] == [f"{fo['median']:.2f}", f"{fo['p95']:.2f}", str(fo["count"])]
        view.screenshot(path=str(out.parent / "index_page.png"), full_page=True)  # the test's artefact, beside RUN
        view.click("#photos tbody tr:nth-child(2) a")
        view.wait_for_load_state("load")
        assert view.url == (out / "report" / "view1" / "report.html").as_uri()
    assert not errors, errors
    assert all(url.startswith(("file://", "data:")) for url in requests), requests
    assert (out.parent / "index_page.png").stat().st_size > 1000


@pytest.mark.heavy  # 2-3 minutes: a whole verify run of three photos, `make test-heavy`
def test_a_run_of_three_photos_indexes_three_reports(dataset: Path, tmp_path: Path) -> None:
    """Issue 27: a dataset of three photos, the draft's two views and view0 taken again 1 EV
    darker (synth's own bracket frame, copied into photos/), verified as a user would with a
    study's folder: RUN/index.html has one row per photo, each row's link opens that photo's
    report in chromium, and the index and every report show the study's figure."""
    import shutil

    from renderer.render_study import RenderStudyConfig, run_render_study
    from tests.browser import chromium_page

    three = tmp_path / "dataset"
    shutil.copytree(dataset, three)
    shutil.copy(dataset / "brackets" / "ev-1.dng", three / "photos" / "view0_ev-1.dng")
    study = tmp_path / "study"  # a small `workbench study render`: its figure goes into the reports and the index
    run_render_study("cornell_cd", study, RenderStudyConfig(resolution=(80, 60), spp_steps=(8, 32), reference_spp=64,
                                                            deltas=(0.4,), delta_spp=16, furnace_samples=10_000),
                     progress=False)
    out = tmp_path / "run"
    record = verify(three, "cornell_cd", out, VerifySettings(spp=SPP, progress=False, studies=(str(study),)))
    index = Path(record["summary"]["index"])
    with chromium_page(index, {"width": 1200, "height": 900}) as (view, errors, requests):
        assert view.evaluate("Array.from(document.querySelectorAll('img.study'))"
                             ".filter(i => i.complete && i.naturalWidth > 0).length") == 1
        rows = view.evaluate("Array.from(document.querySelectorAll('#photos tbody tr')).map(r => ({"
                             "href: r.querySelector('a').getAttribute('href'), name: r.querySelector('td').innerText.trim()}))")
        assert sorted(r["name"] for r in rows) == ["view0.dng", "view0_ev-1.dng", "view1.dng"]
        for number, row in enumerate(rows, start=1):
            view.goto(index.as_uri())
            view.click(f"#photos tbody tr:nth-child({number}) a")
            view.wait_for_load_state("load")
            assert view.url == (out / row["href"]).as_uri() and (out / row["href"]).is_file()
            assert Path(row["name"]).stem in view.inner_text("h1")
            assert view.evaluate("document.querySelectorAll('img.study').length") == 1
    assert not errors, errors
    assert all(url.startswith(("file://", "data:")) for url in requests), requests


@pytest.mark.slow
def test_the_fringe_overlay_draws_the_reports_own_edges_in_chromium(reference: tuple[Path, dict, float]) -> None:
    """Issue 27, item 4, on a page the run wrote: the overlay is hidden until toggled (button, O
    key); it draws one ring per photo band edge and one dot per predicted one that fringes.csv
    lists (quality ok, overlap or clipped; hue crossings are not drawn), as many coloured (paired) rings as report.json's
    photo-render pairs, and at least half of them green exactly when their median offset is
    within 0.5 px."""
    import csv

    from reports.page.fringe_overlay import OFFSET_GOOD_PX, SHOWN_QUALITIES
    from tests.browser import chromium_page

    out, _, _ = reference
    folder = out / "report" / "view0"
    report = json.loads((folder / "report.json").read_text())
    rows = [r for r in csv.DictReader((folder / "fringes.csv").open()) if r["quality"] in SHOWN_QUALITIES
            and r["channel"] != "hue" and all(np.isfinite(float(r[k])) for k in ("position", "x", "y"))]  # band edges
    photo_source = "photo_as_taken" if any(r["source"] == "photo_as_taken" for r in rows) else "photo"
    pairs = report["cd"]["offsets"]["photo_render"]
    with chromium_page(folder / "report.html", {"width": 1400, "height": 1000}) as (view, errors, requests):
        shown = "getComputedStyle(document.getElementById('fringe-overlay')).display"
        assert view.evaluate(shown) == "none"
        view.click("#overlay-toggle")
        assert view.evaluate(shown) != "none" and view.get_attribute("#overlay-toggle", "aria-pressed") == "true"

        def count(selector: str) -> int:
            return int(view.evaluate(f"document.querySelectorAll('#fringe-overlay {selector}').length"))

        assert count("circle.photo") == sum(r["source"] == photo_source for r in rows) > 0
        assert count("circle.prediction") == sum(r["source"] == "prediction" for r in rows)
        paired = count("circle.good") + count("circle.fair") + count("circle.poor")
        assert paired == pairs["count"] and count("path.render") == pairs["count"]
        assert (count("circle.good") >= paired / 2) == (pairs["median"] <= OFFSET_GOOD_PX)
        view.screenshot(path=str(out.parent / "report_overlay.png"))  # the test's artefact, beside RUN
        view.keyboard.press("o")
        assert view.evaluate(shown) == "none"
    assert not errors, errors
    assert all(url.startswith(("file://", "data:")) for url in requests), requests


@pytest.mark.slow
def test_a_rerun_skips_every_stage(reference: tuple[Path, dict, float], dataset: Path,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    out, _, _ = reference
    code = main(["verify", str(dataset), "--scene", "cornell_cd", "--out", str(out), "--spp", str(SPP), "--quiet"])
    printed = capsys.readouterr().out
    record = json.loads((out / "run.json").read_text())
    assert code == 0 and all(s["skipped"] for s in record["stages"].values()), record["stages"]
    assert "report.html" in printed and "pose residual RMS" in printed and "fringe offset" in printed


def _start(dataset: Path, out: Path, log: Path) -> subprocess.Popen:
    with open(log, "ab") as f:
        return subprocess.Popen([sys.executable, "-m", "workbench.cli", "verify", str(dataset), "--scene", "cornell_cd",
                                 "--out", str(out), "--spp", str(SPP), "--quiet"], stdout=f, stderr=subprocess.STDOUT)


def _kill_when(process: subprocess.Popen, ready, log: Path) -> None:
    deadline = time.monotonic() + KILL_TIMEOUT_S
    while not ready():
        assert process.poll() is None, f"verify ended before it could be killed:\n{log.read_text()}"
        assert time.monotonic() < deadline, "timed out waiting for the stage"
        time.sleep(KILL_POLL_S)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()


def _stage_status(out: Path, name: str) -> str | None:
    try:
        return json.loads((out / "run.json").read_text())["stages"].get(name, {}).get("status")
    except (OSError, ValueError, KeyError):
        return None


def _assert_same_calibration(ours: dict, theirs: dict) -> None:
    from workbench.score import centre_error_mm, rotation_error_deg

    a, b = ours["camera"], theirs["camera"]
    for key in ("fx", "fy", "cx", "cy"):
        assert a[key] == pytest.approx(b[key], rel=SAME_INTRINSICS), key
    np.testing.assert_allclose(a["dist"], b["dist"], rtol=SAME_INTRINSICS, atol=SAME_INTRINSICS)
    for photo in b["world_to_camera"]:
        pose_a, pose_b = np.array(a["world_to_camera"][photo]), np.array(b["world_to_camera"][photo])
        assert rotation_error_deg(pose_a, pose_b) < SAME_ROTATION_DEG, photo
        assert centre_error_mm(pose_a, pose_b) < SAME_CENTRE_MM, photo
        assert ours["exposure_scale"][photo] == pytest.approx(theirs["exposure_scale"][photo], rel=SAME_EXPOSURE), photo
        assert abs(ours["residuals"][photo]["rms_px"] - theirs["residuals"][photo]["rms_px"]) < SAME_RESIDUAL_PX, photo
    np.testing.assert_allclose(ours["response"]["points"], theirs["response"]["points"], rtol=SAME_INTRINSICS,
                               atol=SAME_INTRINSICS)  # from the bracket alone: no render, round-off only


@pytest.mark.heavy  # 3.5 minutes: a second whole verify run (calibration and scene fit), `make test-heavy`
def test_a_run_killed_during_calibration_and_rendering_resumes_to_the_same_result(
        reference: tuple[Path, dict, float], dataset: Path, tmp_path: Path) -> None:
    ref, _, _ = reference
    out, log = tmp_path / "run", tmp_path / "verify.log"

    def in_calibration() -> bool:  # the stage is running (it takes 15-45 s here); decided by run.json, not a clock
        return _stage_status(out, "calibration") == "running" and (out / ".staging" / "calibration").is_dir()

    _kill_when(_start(dataset, out, log), in_calibration, log)
    assert not (out / "calibration").exists() and (out / "tables" / ".stage-key").is_file()

    first_render = out / ".staging" / "render" / "view0.exr"
    _kill_when(_start(dataset, out, log), lambda: first_render.is_file() and first_render.with_suffix(".json").is_file(),
               log)
    assert not (out / "render").exists() and (out / "calibration" / ".stage-key").is_file()

    finished = _start(dataset, out, log)
    assert finished.wait(timeout=KILL_TIMEOUT_S) == 0, log.read_text()
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "finished"
    assert record["stages"]["calibration"]["skipped"]  # finished before the second kill: not computed again
    renders = record["stages"]["render"]["result"]["renders"]  # by output name (the fitted scenes': stage rerender)
    assert renders["view0"]["served"] and not renders["view1"]["served"]  # view0 kept from the killed run

    ours, theirs = (json.loads((d / "calibration" / "calibration.json").read_text()) for d in (out, ref))
    _assert_same_calibration(ours, theirs)
    from renderer.render import render
    from reports.compare.images import read_linear

    fresh = render(out / "calibration" / "scenes" / "view0.toml", tmp_path / "fresh.exr", spp=SPP, resolution=(640, 480),
                   progress=False)  # what the killed run had rendered, made again without interruption
    kept = read_linear(out / "render" / "view0.exr", "render")
    np.testing.assert_allclose(kept, read_linear(Path(fresh["output"]), "render"), rtol=PIXELS_RELATIVE, atol=0)


@pytest.mark.slow
def test_score_prints_and_writes_the_errors(reference: tuple[Path, dict, float], dataset: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    out, _, _ = reference
    code = main(["score", str(out), "--truth", str(dataset / "truth.json")])
    printed = capsys.readouterr().out
    score = json.loads((out / "score.json").read_text())
    errors = score["calibration"]
    assert code == 0 and errors["rotation_deg"] < ROTATION_BAR_DEG and errors["centre_mm"] < CENTRE_BAR_MM, errors
    for key in ("fov_deg", "principal_point_pct", "exposure_light_pct", "response_rms_pct"):
        assert errors[key] is not None and errors[key] >= 0, key
    assert sorted(score["fringe_offset_px"]) == ["view0.dng", "view1.dng"]
    assert f"{errors['rotation_deg']:.3g} deg" in printed and "fringe offset" in printed


# ---------------------------------------------------------------- bad input (no dataset needed)


def _fake_dataset(root: Path, size: tuple[int, int] = (64, 48)) -> Path:
    from PIL import Image

    (root / "photos").mkdir(parents=True)
    Image.fromarray(np.full((size[1], size[0], 3), 128, np.uint8)).save(root / "photos" / "view0.png")
    return root


def _error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    code: int | str | None
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error:") and "Traceback" not in err, err
    return err


def test_a_dataset_without_photos_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "data" / "photos").mkdir(parents=True)
    err = _error(["verify", str(tmp_path / "data"), "--scene", "cornell_cd", "--out", str(tmp_path / "run")], capsys)
    assert str(tmp_path / "data" / "photos") in err and "no photos" in err
    assert not (tmp_path / "run").exists()  # refused before anything was written


def test_a_study_folder_without_figures_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _fake_dataset(tmp_path / "data")
    (tmp_path / "study").mkdir()
    (tmp_path / "study" / "notes.txt").write_text("not a figure")
    err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(tmp_path / "run"), "--study",
                  str(tmp_path / "study")], capsys)
    assert "--study" in err and str(tmp_path / "study") in err and "study_*.png" in err
    assert not (tmp_path / "run").exists()  # refused before anything was written


def test_a_scene_the_photos_do_not_match_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _fake_dataset(tmp_path / "data", (64, 36))  # 16:9 photos; cornell_cd's camera is 326 x 245 (4:3)
    err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(tmp_path / "run")], capsys)
    assert "camera.resolution" in err and "64 x 36" in err and "326 x 245" in err
    assert not (tmp_path / "run").exists()


def test_a_run_folder_of_another_run_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _fake_dataset(tmp_path / "data")  # 64 x 48: cornell_cd's aspect
    other = tmp_path / "run"
    other.mkdir()
    (other / "run.json").write_text(json.dumps({"format": "workbench-verify", "stages": {},
                                                "identity": {"dataset": "/elsewhere", "scene": "cornell_cd"}}))
    err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(other)], capsys)
    assert str(other / "run.json") in err and "another run" in err and "/elsewhere" in err and "--force" in err

    foreign = tmp_path / "photos_of_mine"
    foreign.mkdir()
    (foreign / "holiday.jpg").write_bytes(b"")
    err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(foreign)], capsys)
    assert "holiday.jpg" in err and "no verify run wrote" in err


def test_force_replaces_another_run_and_only_what_a_run_writes(tmp_path: Path) -> None:
    root = tmp_path / "run"
    (root / "render").mkdir(parents=True)
    (root / "render" / "view0.exr").write_bytes(b"old")
    (root / "notes.txt").write_text("mine")
    (root / "run.json").write_text(json.dumps({"format": "workbench-verify", "stages": {"render": {}},
                                               "identity": {"dataset": "/elsewhere", "scene": "x"}}))
    identity = {"dataset": "/here", "scene": "cornell_cd"}
    record = open_run(root, identity, VerifySettings(), force=True)
    assert record["identity"] == identity and record["stages"] == {}
    assert not (root / "render").exists() and not (root / "run.json").exists() and (root / "notes.txt").read_text() == "mine"


def test_a_second_run_into_the_same_folder_is_refused_while_the_first_runs(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two verify runs writing one RUN would interleave their stages: the second is refused, naming the folder,
    and nothing of the first is touched (here the first is held by this process's lock on the same file)."""
    from filelock import FileLock

    data = _fake_dataset(tmp_path / "data")
    root = tmp_path / "run"
    root.mkdir()
    (root / "notes.txt").write_text("the first run's")
    with FileLock(str(tmp_path / ".run.verify.lock")):
        err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(root)], capsys)
    assert "another verify run is writing into this folder" in err and str(root) in err
    assert sorted(p.name for p in root.iterdir()) == ["notes.txt"]


def _raw_dataset(root: Path, board: bool = False) -> tuple[Path, Path]:
    """A dataset whose photo is a whole 64 x 48 DNG (cornell_cd's aspect) from datasets_synthetic.dng, with a board
    view in calibration/ that is one too; returns (dataset, photo)."""
    from datasets_synthetic.dng import DngMetadata, write_dng

    raw = np.random.default_rng(3).normal(6000, 300, (48, 64)).clip(0, 16383).astype(np.uint16)
    for folder in ("photos", "calibration") if board else ("photos",):
        (root / folder).mkdir(parents=True)
        write_dng(root / folder / "view0.dng", raw, DngMetadata(black_level=512))
    return root, root / "photos" / "view0.dng"


def _damage(path: Path, how: str) -> None:
    """Cut ``path`` at its first image byte (a header claiming the full size, like issue 26's 13 kB DNG), or zero
    all its samples but the first row (image data missing below the black level)."""
    import tifffile

    with tifffile.TiffFile(path) as tif:
        start = min(tif.pages.first.dataoffsets)
    data = bytearray(path.read_bytes())
    if how == "truncated":
        del data[start:]
    else:
        data[start + 2 * 64:] = bytes(len(data) - start - 2 * 64)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize(("how", "words"), [("truncated", "truncated: its 64 x 48 raw image's data"),
                                            ("zeroed", "damaged image data")])
def test_a_damaged_raw_photo_is_refused_before_any_stage(how: str, words: str, tmp_path: Path,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    """A DNG the project writes, damaged: verify's up-front size check refuses it with the decode's own one-line
    message (calibration.raw.checks), before any stage runs, so RUN is never created."""
    data, photo = _raw_dataset(tmp_path / "data")
    _damage(photo, how)
    err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(tmp_path / "run")], capsys)
    assert str(photo) in err and words in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "run").exists()
    assert main(["decode", str(photo), "--out", str(tmp_path / "o.exr")]) == 2
    assert capsys.readouterr().err == err  # word for word the refusal decode (and so calibration) gives


def test_a_damaged_raw_board_view_is_refused_before_any_stage(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """A board view is decoded only in the calibration stage, after the plan and the tables: it is checked up
    front too. The whole files pass the same check (the control)."""
    from workbench.verify import _check_sizes

    data, photo = _raw_dataset(tmp_path / "data", board=True)
    assert _check_sizes(data, "cornell_cd", (326, 245)) == (64, 48)
    board = data / "calibration" / "view0.dng"
    _damage(board, "truncated")
    err = _error(["verify", str(data), "--scene", "cornell_cd", "--out", str(tmp_path / "run")], capsys)
    assert str(board) in err and "truncated" in err and str(photo) not in err, err
    assert not (tmp_path / "run").exists()


def test_score_refuses_a_folder_that_is_not_a_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err = _error(["score", str(tmp_path), "--truth", str(tmp_path / "truth.json")], capsys)
    assert str(tmp_path / "run.json") in err and "not a verify run" in err


@pytest.mark.heavy  # a dask cluster's start and a render and report on it: 70 s; test_verify_dask.py is its peer
def test_the_render_stage_runs_on_a_dask_scheduler(reference: tuple[Path, dict, float], dataset: Path,
                                                   tmp_path: Path) -> None:
    """--scheduler ADDRESS: a copy of the reference run without its render and report stages,
    resumed with a loopback LocalCluster (one worker process): the finished stages are
    skipped, and the renders made on the cluster equal the local ones (every pass has its
    own seed wherever it runs; float round-off tolerance, as tests/renderer/test_scene_render.py)."""
    import shutil

    import OpenImageIO as oiio
    from distributed import LocalCluster

    out = tmp_path / "run"
    shutil.copytree(reference[0], out)
    for stage in ("render", "report"):
        shutil.rmtree(out / stage)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as cluster:
        record = verify(dataset, "cornell_cd", out, VerifySettings(spp=SPP, progress=False,
                                                                   scheduler=cluster.scheduler_address))
    stages = record["stages"]
    assert all(stages[name]["skipped"] for name in ("plan", "tables", "calibration")), stages
    assert not stages["render"]["skipped"] and not stages["report"]["skipped"]
    for photo in ("view0", "view1"):
        local = oiio.ImageBuf(str(reference[0] / "render" / f"{photo}.exr")).get_pixels()
        remote = oiio.ImageBuf(str(out / "render" / f"{photo}.exr")).get_pixels()
        assert np.allclose(local, remote, rtol=1e-4, atol=1e-6)


def test_a_truncated_run_record_keeps_every_intact_stage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 46, cause 9: a truncated run.json made the rerun refuse its own stage folders as written by no
    verify run, and --force then recomputed every stage. Now the record starts anew (said on stderr) and a
    stage whose key file matches is skipped, its work not run again."""
    from workbench.verify_run import Run, run_stage

    root = tmp_path / "run"
    identity = {"dataset": str(tmp_path), "scene": "cornell_cd"}
    calls: list[Path] = []

    def work(folder: Path) -> dict:
        calls.append(folder)
        (folder / "out.txt").write_text("computed")
        return {"value": 1}

    def run_once() -> dict:
        run = Run(root, open_run(root, identity, VerifySettings(), force=False), tmp_path, [], (4, 3), VerifySettings())
        return run_stage(run, "plan", {}, {"k": 1}, 1.0, work)

    assert run_once()["status"] == "done" and len(calls) == 1
    text = (root / "run.json").read_text()
    (root / "run.json").write_text(text[: len(text) // 2])  # killed mid-write by a tool that did not write atomically
    entry = run_once()
    assert entry["skipped"] and entry["result"] == {"value": 1} and len(calls) == 1  # reused, not recomputed
    assert "could not be read" in capsys.readouterr().err
