"""Renders with planned tables (renderer.trace.planner -> rcwa.table.NodePlan) equal renders with
whole tables within Monte Carlo noise (issue 16), for cornell_cd, cornell_cd_view2 and
grating2d_gold.

Small tables (a coarse grid, few orders) keep it quick; what is tested is the plan: the
nodes the camera's rays read are solved as in the whole table, the others with only the
kept orders. Statistic: per region (the whole image, the element's pixels, the rest) and
channel, the mean of planned - whole (same seed) against the standard error of a mean
difference measured between two whole-table renders of other seeds; |z| < Z_MAX. The
negative control shows the test can fail: a plan that marks no node (every lookup from
the fill) moves grating2d_gold's element by many standard errors (measured: 5-12).

Noise allowed (issue 23): the renders' Monte Carlo noise only (no photo). It is measured
from the data: the standard error is that of a difference of two independent renders
(seeds 1 and 2), from the per-pixel spread over the region's pixels (box filter and
independent sampler: pixels independent; 190-8320 pixels, so the estimate is good to a few
%). Planned and whole share seed 1, so their difference is far less noisy than that
(measured: 0-3.4 % of the independent spread; cornell_cd bitwise 0), which makes the bound
conservative. Comparisons: 9 per scene (3 regions x 3 channels), 27 in the file. False
alarms, Gaussian tail with the union bound: 9 x 2 Q(5.5) = 3.4e-7 per scene, 1.0e-6 for the
file (it was 9 x 2 Q(4) = 5.7e-4 per scene, 1.7e-3 for the file). Smallest defect caught
(Z_MAX standard errors; measured relative standard errors at this size and spp): a bias of
0.5 % over grating2d_gold's image or the rest of its scene, 7-11 % in its element's pixels,
5-7 % over cornell_cd's image, 1.7-2.6 % over the rest of it; the CD's own 190 pixels are noisy (8-10 % standard error),
so there only a bias over ~50 % is caught, and the negative control carries the check.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rcwa.table import NodePlan
from renderer.render import with_resolution
from renderer.scene import load_scene
from workbench.core.cache import ENVIRONMENT_VARIABLE

Z_MAX = 5.5         # on each of 9 (region, channel) means: 9 x 2 Q(5.5) = 3.4e-7 false alarms per scene
NEGATIVE_Z = Z_MAX  # the all-fill control must fail the test's own bound on the element in some channel
SIZE = (96, 72)
SPP = 64
SMALL_TABLES = {
    "cd": {"preset": "draft", "wavelengths": "400:700:7", "theta_step": 10.0, "phi_step": 15.0, "orders": 21, "keep": 7},
    "grating": {"preset": "draft", "wavelengths": "400:700:7", "theta_step": 10.0, "phi_step": 15.0, "orders": [5, 5],
                "keep": [3, 3]},
}


def _small(name: str):
    spec = with_resolution(load_scene(name), SIZE)
    return dataclasses.replace(spec, cds=tuple(dataclasses.replace(c, table=SMALL_TABLES["cd"]) for c in spec.cds),
                               gratings=tuple(dataclasses.replace(g, table=SMALL_TABLES["grating"]) for g in spec.gratings))


def _renders(spec, monkeypatch, nodes_rule=None) -> dict[str, np.ndarray]:
    from renderer import mitsuba_scene as build
    from renderer.accuracy import element_mask
    from renderer.variant import set_variant

    set_variant()
    import mitsuba as mi

    if nodes_rule is not None:
        original = build.planned_nodes
        monkeypatch.setattr(build, "planned_nodes", lambda s: {k: nodes_rule(v) for k, v in original(s).items()})
    planned_d, planned_built = build.scene_dict(mi, spec, spp=SPP, plan=True)  # first: a whole table would serve it
    whole_d, _ = build.scene_dict(mi, spec, spp=SPP, plan=False)
    assert all("-planned-" in path for path in planned_built["tables"])
    render = lambda d, seed: np.array(mi.render(mi.load_dict(d), seed=seed))  # noqa: E731
    return {"planned": render(planned_d, 1), "whole": render(whole_d, 1), "whole_other": render(whole_d, 2),
            "element": element_mask(mi, whole_d)}


def _z_scores(r: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    regions = {"image": np.ones(r["element"].shape, bool), "element": r["element"], "rest": ~r["element"]}
    out = {}
    for name, sel in regions.items():
        se = (r["whole"] - r["whole_other"])[sel].std(axis=0) / np.sqrt(sel.sum())
        out[name] = (r["planned"] - r["whole"])[sel].mean(axis=0) / np.maximum(se, 1e-30)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["cornell_cd", "cornell_cd_view2", "grating2d_gold"])
def test_planned_tables_render_as_whole_tables(scene: str, tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))  # no whole table to serve the plan
    z = _z_scores(_renders(_small(scene), monkeypatch))
    for region, values in z.items():
        assert np.all(np.abs(values) < Z_MAX), (region, values)


@pytest.mark.slow
def test_a_plan_that_marks_no_node_is_caught(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    r = _renders(_small("grating2d_gold"), monkeypatch, lambda n: NodePlan(np.zeros_like(n.mask), n.fill_orders))
    assert np.abs(_z_scores(r)["element"]).max() > NEGATIVE_Z


def test_a_planned_table_serves_every_plan_it_covers(tmp_path, monkeypatch) -> None:
    """A finished planned table whose exact nodes include a new plan's (same fill) serves it;
    one that misses a node does not (a new planned table is built)."""
    from rcwa.table import build_table
    from renderer.tables import table_plan

    monkeypatch.setenv(ENVIRONMENT_VARIABLE, str(tmp_path / "cache"))
    spec = _small("cornell_cd")
    cd = spec.cds[0]
    first = table_plan(cd, "cd[0]", None, _checkerboard(table_plan(cd).settings, (7,)))
    build_table(first.structure, first.settings, first.path, progress=False, nodes=first.nodes)
    subset = NodePlan(first.nodes.mask & (np.arange(first.nodes.mask.shape[0]) < 3)[:, None, None], (7,))
    assert table_plan(cd, "cd[0]", None, subset).path == first.path
    other = NodePlan(~first.nodes.mask, (7,))
    assert table_plan(cd, "cd[0]", None, other).path != first.path
    assert table_plan(cd, "cd[0]", None, NodePlan(subset.mask, (9,))).path != first.path  # another fill


def _checkerboard(settings, fill: tuple[int, ...]) -> NodePlan:
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg))
    return NodePlan(np.indices(shape).sum(axis=0) % 2 == 0, fill)
