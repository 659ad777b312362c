"""The report states the truncation error each efficiency table it used records
(reports/table_error.py, issue 29 item 3): the largest difference against the lower
truncation, per table, in report.json and on the page; "not recorded" for a table built
before tables recorded it; and why, for a table that cannot be read.

The table is a real one, built by ``workbench rcwa table`` (2 wavelengths, a 30 deg grid:
under a second); the render is a synthetic EXR with a sidecar naming the tables, as
renderer.render writes it; the camera looks away from the CD, so the report runs in
about 5 s (tests/reports/test_report.py). The numbers on the page and in report.json
are the table's own records, compared exactly (the page prints them to 3 figures)."""

import json
import shutil

from rcwa.table import read_table_metadata
from renderer.render import SIDECAR_FORMAT
from reports.table_error import report_tables, table_entry, tables_html
from tests.rcwa.test_table_truncation import strip_records
from tests.reports.test_report import _calibration, _camera, _flat, _run, _write_exr
from workbench.cli import main
from workbench.core.files import file_sha256


def _away(camera):
    """The test camera turned 40 deg toward the left wall, away from the CD."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    turn = Rotation.from_rotvec(np.radians([0.0, -40.0, 0.0])).as_matrix()
    pose = camera.world_to_camera.copy()
    pose[:3, :3], pose[:3, 3] = turn @ pose[:3, :3], turn @ pose[:3, 3]
    return camera.__class__(camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, camera.dist, pose)


def test_the_report_states_each_tables_truncation_error(tmp_path, capsys):
    new, old, missing = tmp_path / "new.zarr", tmp_path / "old.zarr", tmp_path / "missing.zarr"
    assert main(["rcwa", "table", "cd", "--out", str(new), "--preset", "draft", "--wavelengths", "500,600",
                 "--theta-step", "30", "--phi-step", "30", "--orders", "21", "--keep-orders", "7", "--quiet"]) == 0
    shutil.copytree(new, old)
    strip_records(old)
    records = read_table_metadata(new)["truncation_error"]
    worst = max((r["truncation"] for r in records.values()), key=lambda t: t["max_difference"])
    photo = _write_exr(tmp_path / "photo.exr", _flat())
    render = _write_exr(tmp_path / "render.exr", _flat(seed=1))
    render.with_suffix(".json").write_text(json.dumps({"format": SIDECAR_FORMAT, "output_sha256": file_sha256(render),
                                                       "tables": [str(new), str(old), str(missing)]}))

    code, text = _run(tmp_path, capsys, photo, render, _calibration(tmp_path / "c.json", _away(_camera())))
    assert code == 0, text
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    by_path = {t["path"]: t for t in report["tables"]}
    assert list(by_path) == [str(new), str(old), str(missing)]
    recorded = by_path[str(new)]
    assert recorded["status"] == "recorded" and recorded["used_by"] == ["render"]
    assert recorded["largest_vs_lower_truncation"]["max_difference"] == worst["max_difference"]
    assert recorded["largest_vs_other_rule"] is None  # 1D: no other factorization rule
    assert [w["vs_lower_truncation"] for w in recorded["per_wavelength"]] == [
        records[i]["truncation"]["max_difference"] for i in ("0", "1")]
    assert by_path[str(old)]["status"] == "not recorded"
    assert by_path[str(missing)]["status"].startswith("not readable")
    assert any("old.zarr: its truncation error is not recorded" in m for m in report["messages"])
    page = (tmp_path / "out" / "report.html").read_text()
    section = page[page.index("efficiency tables (their own truncation error)"):]
    assert f"{worst['max_difference']:.2e} against 11 orders" in section and "not recorded" in section

    # the prediction's table joins the render's entry, or gets its own
    both = report_tables(render, str(new))
    assert both[0]["used_by"] == ["render", "prediction"] and len(both) == 3


def test_a_2d_tables_entry_states_the_other_factorization_rule(tmp_path, capsys):
    """gold2d (rectangles: Li's rule) is also compared with the normal-vector method."""
    out = tmp_path / "g.zarr"
    assert main(["rcwa", "table", "gold2d", "--out", str(out), "--preset", "draft", "--wavelengths", "550",
                 "--theta-step", "45", "--phi-step", "45", "--orders", "5", "--keep-orders", "3", "--quiet"]) == 0
    record = read_table_metadata(out)["truncation_error"]["0"]
    entry = table_entry(out, ["render"])
    assert entry["largest_vs_other_rule"]["max_difference"] == record["factorization"]["max_difference"]
    assert entry["largest_vs_lower_truncation"]["lower_orders"] == [3, 3]
    html = tables_html([entry])
    assert f"{record['factorization']['max_difference']:.2e} against nv rule" in html, html
    assert f"{record['truncation']['max_difference']:.2e} against 3x3 orders" in html, html
