"""Where the CD's shadow makes an edge near its rim (reports.fringes.cd_shadow).

Geometry only, on cornell_cd: its CD leans 20 deg toward the camera, so its near edge is
2.6 mm above the floor and the ceiling light's shadow of the disc touches it there, while
the far edge stands 4.3 cm up and its shadow falls behind the disc, out of the camera's view
of the rim. Point-light tests use the umbra and the open floor, where the lit fraction is
exactly 0 or 1 whatever the light grid.
"""

import numpy as np
import pytest

from renderer.render import with_resolution
from renderer.scene import load_scene
from renderer.trace.prediction import cd_geometry
from reports.fringes import cd_shadow as rim_clutter
from reports.fringes import rim

RESOLUTION = (640, 480)
RIM_COUNT = 96


@pytest.fixture(scope="module")
def scene():
    return with_resolution(load_scene("cornell_cd"), RESOLUTION)


def test_light_samples_fill_the_light_rectangle(scene):
    samples = rim_clutter.light_samples(scene, grid=4)
    assert samples.shape == (16, 3)
    np.testing.assert_allclose(samples.mean(axis=0), scene.light.center, atol=1e-12)  # symmetric cell centres
    np.testing.assert_allclose(np.ptp(samples[:, [0, 2]], axis=0), 0.75 * np.asarray(scene.light.size), rtol=1e-12)


def test_first_wall_hit_is_the_floor_below_and_none_out_of_the_open_front(scene):
    origin = np.array([0.28, 0.30, 0.28])
    hits = rim_clutter.first_wall_hits(scene, origin, np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]))
    np.testing.assert_allclose(hits[0], [0.28, 0.0, 0.28], atol=1e-12)
    assert np.all(np.isnan(hits[1]))  # the box has no wall at z = 0
    assert hits[2][0] == pytest.approx(0.5496, abs=0.01)  # the left wall, within its slant


def test_lit_fraction_is_zero_under_the_annulus_and_one_on_the_open_floor(scene):
    cd = cd_geometry(scene)
    lights = rim_clutter.light_samples(scene)
    under_annulus = cd.center + 0.04 * cd.frame[:, 0]  # mid-annulus, on the disc's x axis
    under_annulus = under_annulus * [1.0, 0.0, 1.0]  # straight down to the floor, 2.3 cm below
    open_floor = np.array([0.05, 0.0, 0.50])
    np.testing.assert_array_equal(rim_clutter.lit_fraction(np.stack([under_annulus, open_floor]), lights, cd), [0.0, 1.0])


def test_a_point_above_the_disc_is_not_shadowed(scene):
    cd = cd_geometry(scene)
    above = cd.center + 0.01 * cd.normal  # between the disc and the light: segments leave away from it
    assert rim_clutter.lit_fraction(above[None], rim_clutter.light_samples(scene), cd)[0] == 1.0


def test_shadow_border_is_in_reach_on_the_near_half_of_the_rim_only(scene):
    camera = scene.camera.model
    cd = cd_geometry(scene)
    expected, clear = rim_clutter.clear_rim(scene, camera, cd, RIM_COUNT, rim.RIM_SEARCH_PX)
    below_centre = expected[:, 1] > expected[:, 1].mean()  # image y grows downward: the near half
    assert np.all(clear[~below_centre])  # the far half's shadow lies behind the disc
    assert 0.25 * RIM_COUNT <= np.sum(~clear) <= 0.5 * RIM_COUNT  # around the lowest, nearest part
    lowest = np.argmax(expected[:, 1])
    assert not clear[lowest]
