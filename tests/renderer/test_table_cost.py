"""The planner's cost estimate of a table's truncation-error sample (renderer.table_cost,
issue 29 item 3): it counts the nodes a build samples, it is part of the table's
estimated seconds, and the plan names it on a line of its own.

How close its seconds come to a build's record is measured, not asserted (a test reads no
clock): ``python -m benchmarks.bench_truncation_cost`` (docs/measurements.md)."""

from __future__ import annotations

import numpy as np

import rcwa
from rcwa.table import NodePlan, build_table, planned, read_table_metadata, settings_for
from rcwa.table.truncation import sample_count
from renderer.scene import load_scene
from renderer.table_cost import table_cost, truncation_counts
from renderer.trace.planner import format_plan, plan_scene


def _cd_settings():
    """100 nodes a wavelength: 3 sampled (one per 30 nodes, rcwa.table.truncation)."""
    return settings_for(rcwa.load_structure("cd"), "draft", wavelengths="500,600", theta_step=10.0, phi_step=10.0,
                        orders=21, keep=7)


def test_the_estimate_counts_the_nodes_a_build_samples(tmp_path):
    """Whole and planned: per wavelength, the nodes the estimate prices are the nodes the
    build's record holds (a planned table samples only its exact nodes, none at a
    wavelength the camera does not need)."""
    s, st = rcwa.load_structure("cd"), _cd_settings()
    shape = (len(st.wavelengths_nm), len(st.theta_deg), len(st.phi_deg))
    mask = np.zeros(shape, bool)
    mask[0].flat[:70] = True  # 70 exact nodes at 500 nm (2 sampled), none at 600 nm
    build_table(s, st, tmp_path / "whole.zarr", progress=False)
    nodes = NodePlan(mask, (11,))
    build_table(s, planned(st, nodes), tmp_path / "planned.zarr", progress=False, nodes=nodes)
    for path, exact, expected in ((tmp_path / "whole.zarr", None, [3, 3]), (tmp_path / "planned.zarr", mask, [2, 0])):
        records = read_table_metadata(path)["truncation_error"]
        recorded = [len(records[str(i)]["nodes"]) for i in range(len(st.wavelengths_nm))]
        assert truncation_counts(st, exact) == recorded == expected


def test_the_sample_is_part_of_the_tables_estimated_seconds():
    s, st = rcwa.load_structure("cd"), _cd_settings()
    shape = (len(st.wavelengths_nm), len(st.theta_deg), len(st.phi_deg))
    none = np.zeros(shape, bool)
    masks = {"R": none.copy(), "T": none.copy(), "R_below": none.copy(), "T_below": none.copy()}
    masks["R"][0, 0, :3] = True  # 3 exact nodes at 500 nm: one sampled
    cost = table_cost(s, st, see_through=False, kept_orders=7, masks=masks, measure=True)
    t = cost.truncation
    assert (t.nodes_whole, t.nodes_planned, t.lower_orders, t.other_rule) == (6, 1, (11,), None)
    assert 0 < t.seconds_whole < cost.seconds_whole and 0 < t.seconds_planned < cost.seconds_planned
    masks["R"][:] = False  # the camera needs no node: the planned table samples nothing
    assert table_cost(s, st, False, 7, masks, measure=True).truncation.seconds_planned == 0.0
    unmeasured = table_cost(s, st, False, 7, masks, measure=False)
    assert unmeasured.truncation.seconds_whole == unmeasured.seconds_whole == 0.0


def test_the_plan_names_the_truncation_sample():
    """gold2d (2D): again at the lower truncation and with the normal-vector method, the
    draft grid's 114 nodes a wavelength sampled 3 times; the CD (1D): the lower truncation only."""
    gold = load_scene("grating2d_gold")
    plan = plan_scene(gold, measure_cost=False)
    (plate,) = plan.elements
    per_wavelength = len(plate.grid_theta_deg) * len(plate.grid_phi_deg)
    wavelengths = plate.directions_total // per_wavelength
    t = plate.truncation
    assert t["nodes_whole"] == wavelengths * sample_count(per_wavelength) == 11 * 3
    assert 0 < t["nodes_planned"] <= t["nodes_whole"]
    text = format_plan(plan)
    assert (f"truncation    error sampled at {t['nodes_whole']} nodes ({t['nodes_planned']} planned), solved again at "
            "5x5 orders and with the nv rule on one thread") in text, text
    text = format_plan(plan_scene(load_scene("cornell_cd_view2"), measure_cost=False))
    line = next(line for line in text.splitlines() if line.startswith("  truncation"))
    assert "solved again at 15 orders on one thread" in line and "rule" not in line, line
