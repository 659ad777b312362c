"""The simulation planner (renderer/trace/planner.py): what a scene needs, from geometry and the
grating equation alone (no table is built, no render runs)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rcwa.table import PRESETS, Table, angle_grid
from renderer.scene import load_scene
from renderer.trace.planner import fold_azimuths, incident_directions, plan_scene
from workbench.core.conventions import order_kx

GRATING_EQUATION_TOL = 1e-12  # direction cosines: the planner inverts order_kx exactly, up to round-off
ONE_FIFTH = 0.2  # issue 16: a grating with one groove direction seen by one camera needs at most this


def _replace_element(spec, kind: str, **changes):
    items = getattr(spec, kind)
    return dataclasses.replace(spec, **{kind: (dataclasses.replace(items[0], **changes),) + items[1:]})


def test_incident_directions_invert_the_grating_equation() -> None:
    """Order m sends the planner's incident wave back to the camera's tangential k."""
    rng = np.random.default_rng(3)
    omega_t = rng.uniform(-0.6, 0.6, (200, 2))
    period, lam, n_cam, n_light = (1.6, 1.1), 532.0, 1.58, 1.58
    for m, n in ((-2, 0), (1, 1), (3, -2)):
        theta, phi, ok = incident_directions(omega_t, m, n, lam, period, n_cam, n_light)
        k_inc = (n_light * np.sin(np.radians(theta)))[:, None] * np.stack([np.cos(np.radians(phi)), np.sin(np.radians(phi))], 1)
        back_x = order_kx(k_inc[ok, 0], m, period[0] * 1000.0, lam)
        back_y = order_kx(k_inc[ok, 1], n, period[1] * 1000.0, lam)
        np.testing.assert_allclose(back_x, n_cam * omega_t[ok, 0], atol=GRATING_EQUATION_TOL)
        np.testing.assert_allclose(back_y, n_cam * omega_t[ok, 1], atol=GRATING_EQUATION_TOL)
        assert ok.any() and not ok.all()  # at these orders some incident waves would be evanescent: flagged


@pytest.mark.parametrize(("mirror_x", "mirror_y"), [(False, False), (True, False), (False, True), (True, True)])
def test_fold_azimuths_matches_the_tables_rule(mirror_x: bool, mirror_y: bool) -> None:
    table = Table(path=None, meta={"symmetry": {"mirror_x": mirror_x, "mirror_y": mirror_y}}, arrays={})  # type: ignore[arg-type]
    phis = np.linspace(-400.0, 400.0, 161)
    expected = [table.fold_azimuth(float(p))[0] for p in phis]
    np.testing.assert_allclose(fold_azimuths(phis, mirror_x, mirror_y), expected, atol=1e-12)


def test_scene_without_diffractive_elements_needs_no_rcwa() -> None:
    spec = dataclasses.replace(load_scene("cornell_cd"), cds=())
    plan = plan_scene(spec, measure_cost=False)
    assert not plan.rcwa_needed and not plan.elements


def test_element_out_of_view_is_left_out() -> None:
    spec = _replace_element(load_scene("cornell_cd"), "cds", center=(0.30, 0.0006, -0.9))  # behind the camera
    plan = plan_scene(spec, measure_cost=False)
    (cd,) = plan.elements
    assert cd.visible_pixels == 0 and cd.directions_needed == 0 and not cd.tables and not plan.rcwa_needed


def test_opaque_cd_gets_reflection_only() -> None:
    plan = plan_scene(load_scene("cornell_cd_view2"), measure_cost=False)
    (cd,) = plan.elements
    assert not cd.see_through and cd.tables == ["R"] and cd.visible_pixels > 0


def test_glass_out_of_view_needs_no_dispersion() -> None:
    spec = load_scene("cornell_cd")
    moved = dataclasses.replace(spec.glass[0], center=(0.17, 0.0201, -0.9))
    plan = plan_scene(dataclasses.replace(spec, glass=(moved,) + spec.glass[1:]), measure_cost=False)
    assert not plan.glass[0].dispersion_needed and plan.glass[0].visible_pixels == 0
    assert plan.glass[1].dispersion_needed


def test_fixed_grooves_need_a_small_part_of_the_table_radial_grooves_most_of_it() -> None:
    """gold2d seen by one camera: each order maps the camera's narrow cone to a small patch
    per wavelength chunk, so at the paper's grid at most a fifth of the nodes is needed.
    The CD's radial grooves turn the camera's view into every azimuth of the grating frame.
    Both shares are counted over the azimuths 0-90 deg: gold2d's table is also folded by
    its diagonal mirror (rcwa.symmetry: 0-45 deg stored, half the nodes), onto which each
    order's patch folds without shrinking, so its own fraction doubles."""
    gold = load_scene("grating2d_gold")
    gold = _replace_element(gold, "gratings", table={"preset": "paper"})
    (plate,) = plan_scene(gold, measure_cost=False).elements
    assert plate.see_through and set(plate.tables) == {"R", "T_below"}
    assert "diagonal" in plate.symmetry and plate.grid_phi_deg[-1] < 90.0
    nodes_0_to_90 = plate.directions_total // len(plate.grid_phi_deg) * len(angle_grid(PRESETS["paper"]["phi_step"], 0.0,
                                                                                        90.0, "phi", cover=True))
    share = plate.directions_needed / nodes_0_to_90
    assert 0 < share <= ONE_FIFTH
    cd_scene = _replace_element(load_scene("cornell_cd_view2"), "cds", table={"preset": "paper"})
    (cd,) = plan_scene(cd_scene, measure_cost=False).elements
    assert cd.grid_phi_deg[-1] == 90.0 and cd.fraction > 2 * share
