"""The forward model's offsets measured on a render (reports.scene_fit.bias).

Fast: the rim's offsets are a running median around the closed rim; a band's offset is the
median of its edges' (prediction minus render), one channel where it has enough edges, else
its channels merged; a render without its variance, or one whose CD edges are noisier than
a photo's edge of quality ok, is not used.

Slow, chained as verify chains them: the shared seed-0 dataset (made from the scene file
itself), `calibrate DATASET`, `workbench render --target report` of view0's calibrated
scene, then `workbench fit --renders` on view0. The render's rim offsets must account for
the photo's: the photo's rim lies outside the grating's circle (measured +0.06 px median on
this photo, +0.06..+0.40 px on six datasets' photos), and less the render's offsets its
median is within ``RIM_AGREEMENT_PX`` of 0 (photo against render measured -0.003..+0.08 px
on three datasets, both views).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from reports.fringes import band_edges as fringes
from reports.scene_fit.bias import RIM_BIAS_NEIGHBOURS, band_offsets, rim_offsets, usable_render
from tests.calibration.test_pose import calibrated_dataset
from workbench.cli import main

RIM_AGREEMENT_PX = 0.15  # photo-render rim medians measured -0.003..+0.08 px (6 photos); the render's noise ~0.05 px


def _edge(channel: str, profile: int, position: float, quality: str = "ok") -> fringes.Edge:
    return fringes.Edge("circle", profile, 0.5, 1, channel, 0, "start", position, 0.0, position, 0.0, 0.1, 1.0, 20.0,
                        quality)


class _Line:
    """A polar grid whose profiles run along x (signed_offset reads only kind, pixels' shape and positions)."""

    kind = "radius"
    pixels = np.zeros((64, 8, 2))


def test_rim_offsets_are_a_running_median_around_the_closed_rim() -> None:
    angles = np.linspace(-np.pi, np.pi, 24, endpoint=False)
    residuals = np.full(24, 0.2)
    residuals[0] = 5.0  # one wild point: the median of its 2 * RIM_BIAS_NEIGHBOURS + 1 neighbours ignores it
    residuals[-1] = -0.4  # the rim closes: the last point's neighbours include the first
    sorted_angles, offsets = rim_offsets(angles[::-1], residuals[::-1])
    assert np.all(np.diff(sorted_angles) > 0)
    assert offsets[0] == pytest.approx(0.2) and RIM_BIAS_NEIGHBOURS == 2
    assert offsets[-1] == pytest.approx(0.2)


def test_a_band_offset_is_its_edges_median_else_its_channels_merged() -> None:
    grid = _Line()
    predicted = [_edge(c, p, 10.0) for c in "RG" for p in range(5)]
    rendered = [_edge("R", p, 10.0 - d) for p, d in enumerate([0.3, 0.2, 0.25, 9.0, 0.2])]  # R: 5 edges, one wild
    rendered += [_edge("G", 0, 9.5), _edge("G", 1, 9.4, "weak")]  # G: one edge of quality ok, too few alone
    offsets = band_offsets(rendered, predicted, grid)
    assert offsets[("circle", 0, 1, "R", 0, "start")] == pytest.approx(0.25)  # prediction minus render, median
    merged = np.median([0.3, 0.2, 0.25, 9.0, 0.2, 0.5])
    assert offsets[("circle", 0, 1, "G", 0, "start")] == pytest.approx(merged)


def test_a_render_without_variance_or_too_noisy_is_not_used() -> None:
    y, x = np.mgrid[0:64, 0:64]
    rgb = np.repeat((x >= 32).astype(float)[..., None], 3, axis=2)  # a sharp edge across the CD
    cd = np.ones((64, 64), bool)
    assert usable_render(rgb, None, cd)[0] is False
    assert usable_render(rgb, np.full_like(rgb, 1e-6), cd)[0] is True  # sigma_I 1e-3 at a unit step: 0.003 px
    noisy, note = usable_render(rgb, np.full_like(rgb, 0.04), cd)  # sigma_I 0.2: about 0.5 px at the step
    assert noisy is False and note["render_edge_sigma_px"] > 0.35


@pytest.mark.heavy  # a report-targeted render of view0 and a fit: 2 min on 2 cores
def test_the_renders_rim_offsets_account_for_the_photos(tmp_path_factory, tmp_path: Path) -> None:
    from renderer.scene import load_scene
    from renderer.trace.prediction import cd_geometry
    from reports.scene_fit.job import FitInputs, load_views
    from reports.scene_fit.model import EdgeModel, rim_residuals

    out, _, _ = calibrated_dataset(tmp_path_factory)
    dataset = out.parent / "photos-only"
    renders = tmp_path / "renders"
    assert main(["render", str(out / "scenes" / "view0.toml"), "--out", str(renders / "view0.exr"), "--target", "report",
                 "--quiet"]) == 0
    assert main(["fit", str(dataset), "--scene", "cornell_cd", "--calibration", str(out / "calibration.json"),
                 "--out", str(tmp_path / "fit"), "--photo", "view0.dng", "--renders", str(renders)]) == 0
    record = json.loads((tmp_path / "fit" / "scene_fit.json").read_text())
    note = record["bias_correction"]["view0.dng"]
    assert note["used"] is True and note["render_edge_sigma_px"] <= 0.35 and note["band_edge_keys"] > 20, note

    spec = load_scene("cornell_cd")
    view = load_views(FitInputs(dataset, "cornell_cd", out / "calibration.json", tmp_path / "x", ("view0.dng",),
                                renders=renders), spec)[0]
    bias = EdgeModel(spec, spec.fit, [view]).view_biases()[0]
    assert bias is not None
    raw = rim_residuals(view.camera, cd_geometry(spec), view.rim_points)
    corrected = raw - bias.rim(view.rim_points)
    assert abs(float(np.median(corrected))) < RIM_AGREEMENT_PX, (np.median(raw), np.median(corrected))
