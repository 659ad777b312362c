"""``workbench decode --json`` prints the sensor layout and why its demosaicing was chosen
(calibration.raw.layout), the same values the sidecar records, for a 2 x 2 Bayer DNG and a
LinearRaw DNG (3 samples per pixel, no filter array), both written by datasets_synthetic.dng."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from datasets_synthetic.dng import DngMetadata, write_dng
from workbench.cli import main
from workbench.commands.decode import SUMMARY_KEYS


@pytest.mark.parametrize(("pattern", "shape", "layout", "why"), [
    ("GRBG", (40, 56), "Bayer 2 x 2 (GRBG)", "2 x 2 Bayer: bilinear"),
    ("", (40, 56, 3), "3 samples per pixel (no filter array)", "no colour filter array: each pixel's own 3 samples"),
])
def test_json_summary_names_the_layout_and_the_demosaic_reason(pattern: str, shape: tuple[int, ...], layout: str,
                                                               why: str, tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    samples = np.random.default_rng(11).integers(512, 16384, shape).astype(np.uint16)
    path = write_dng(tmp_path / "raw.dng", samples, DngMetadata(cfa_pattern=pattern, black_level=512))
    assert main(["decode", str(path), "--out", str(tmp_path / "o.exr"), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    sidecar = json.loads((tmp_path / "o.json").read_text())
    assert set(printed) == set(SUMMARY_KEYS) and {"layout", "demosaic_reason"} <= set(printed)
    assert printed["layout"] == layout and printed["demosaic_reason"].startswith(why), printed
    assert all(printed[k] == sidecar[k] for k in SUMMARY_KEYS), (printed, sidecar)
