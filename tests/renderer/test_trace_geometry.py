"""renderer/trace/: the numpy trace's geometry, written once, and its independence from Mitsuba.

Analytic checks: a ray meets a plane where the closed form puts it; an annulus keeps its hole;
the light's rectangle is hit inside its extent only; the grating equation's incident wave
feeds the order that leaves toward the camera (sent forward again, it gives the outgoing
direction back to round-off).
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from renderer.scene import load_scene
from renderer.trace import geometry
from workbench.core.conventions import ORDER_SIGN, order_kx, order_kxy

ROUND_OFF = 1e-12  # float64 arithmetic on numbers of order 1


def test_the_trace_imports_no_mitsuba():
    """The planner, the prediction and their geometry run where Mitsuba does not (a report machine)."""
    code = ("import sys; import renderer.trace.planner, renderer.trace.prediction, renderer.trace.efficiency_weights; "
            "import reports.fringes.cd_shadow, calibration.pose.scene_model; "
            "print(sorted(m for m in ('mitsuba', 'drjit') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr


def test_ray_plane_distance_and_hits():
    origin = np.array([0.0, 1.0, 0.0])
    rays = np.array([[0.0, -1.0, 0.0], [0.6, -0.8, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    points, ok = geometry.plane_hits(origin, rays, np.zeros(3), np.array([0.0, 1.0, 0.0]))
    np.testing.assert_array_equal(ok, [True, True, False, False])  # parallel, and behind
    np.testing.assert_allclose(points[:2], [[0.0, 0.0, 0.0], [0.75, 0.0, 0.0]], atol=ROUND_OFF)


def test_annulus_keeps_its_hole_and_the_segment_end():
    origin = np.array([0.0, 1.0, 0.0])
    down = np.array([0.0, -1.0, 0.0])
    starts = np.array([[0.0, 1.0, 0.0], [0.03, 1.0, 0.0], [0.07, 1.0, 0.0]])  # in the hole, on the disc, outside
    hits = geometry.annulus_hits(starts, np.repeat(down[None], 3, 0), np.zeros(3), np.array([0.0, 1.0, 0.0]),
                                 0.0075, 0.06, 1e-9, np.inf)
    np.testing.assert_array_equal(hits, [False, True, False])
    short = geometry.annulus_hits(origin + [0.03, 0, 0], down[None], np.zeros(3), np.array([0.0, 1.0, 0.0]),
                                  0.0075, 0.06, 1e-9, np.array([0.5]))
    assert not short[0]  # the disc lies beyond the segment's end


def test_light_rectangle_is_hit_inside_its_extent_only():
    spec = load_scene("cornell_cd")
    light = geometry.light_rectangle(spec)
    corners = light.corners()
    assert np.allclose(corners[:, 1], spec.light.center[1])
    np.testing.assert_allclose(corners.max(axis=0)[[0, 2]] - corners.min(axis=0)[[0, 2]], spec.light.size)
    start = np.array([spec.light.center[0], 0.1, spec.light.center[2]])
    up = np.array([0.0, 1.0, 0.0])
    aside = up + np.array([2.0 * spec.light.size[0], 0.0, 0.0]) / (spec.light.center[1] - 0.1)
    np.testing.assert_array_equal(light.hit_by(np.array([start, start, start]), np.array([up, aside, -up])),
                                  [True, False, False])
    grid = light.grid(4)
    assert len(grid) == 16 and np.all(light.hit_by(grid - up, np.repeat(up[None], 16, 0)))


@pytest.mark.parametrize("period", [(1.6,), (0.5, 0.7)])
def test_incident_wave_feeds_the_order_that_leaves_toward_the_camera(period):
    """Forward through the conventions' grating equation (order_kxy), the incident k gives back the outgoing one."""
    rng = np.random.default_rng(3)
    outgoing = rng.uniform(-0.5, 0.5, (20, 2))
    for m, n in [(-1, 0), (1, 1), (2, -1)]:
        n = n if len(period) > 1 else 0
        k_in = geometry.incident_k(outgoing, m, n, 550.0, period)
        if len(period) > 1:
            kx, ky = order_kxy(k_in[:, 0], k_in[:, 1], m, n, tuple(p * 1000.0 for p in period), 550.0)
        else:
            kx, ky = order_kx(k_in[:, 0], m, period[0] * 1000.0, 550.0), k_in[:, 1]
        np.testing.assert_allclose(kx, outgoing[:, 0], atol=ROUND_OFF)
        np.testing.assert_allclose(ky, outgoing[:, 1], atol=ROUND_OFF)
    assert ORDER_SIGN == -1  # the sign the docstring states
