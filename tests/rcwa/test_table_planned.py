"""Planned tables (rcwa.table.NodePlan): the nodes a render reads are solved exactly as in
a whole table, the others with fewer retained orders, and the plan is part of the request.

Tolerance: tables store float32 (6e-8 rounding of efficiencies <= 1); a subset of
directions may be solved in another order by the sweep's k_x-refined eigen-solves, so the
exact nodes must equal the whole table's to 1e-6 absolute, as direct solves do
(tests/rcwa/test_table.py).
"""

import numpy as np
import pytest

import rcwa
from rcwa.table import NodePlan, build_table, open_table, planned, request_key, settings_for
from workbench.core.errors import UserInputError

TOLERANCE_FLOAT32 = 1e-6


def _small(structure, **kw):
    args = dict(wavelengths="450:650:3", theta_step=30.0, phi_step=30.0, orders=21, keep=7)
    args.update(kw)
    return settings_for(structure, "draft", **args)


def _checkerboard_mask(settings) -> np.ndarray:
    shape = (len(settings.wavelengths_nm), len(settings.theta_deg), len(settings.phi_deg))
    return (np.indices(shape).sum(axis=0) % 2 == 0)


def test_exact_nodes_equal_the_whole_table_and_the_rest_the_fill_orders(tmp_path):
    s = rcwa.load_structure("cd")
    whole = _small(s)
    nodes = NodePlan(_checkerboard_mask(whole), (9,))
    build_table(s, planned(whole, nodes), tmp_path / "p.zarr", progress=False, nodes=nodes)
    build_table(s, whole, tmp_path / "w.zarr", progress=False)
    build_table(s, _small(s, orders=9), tmp_path / "f.zarr", progress=False)
    p, w, f = (open_table(tmp_path / name).arrays["R"]
               for name in ("p.zarr", "w.zarr", "f.zarr"))
    mask = nodes.mask
    assert np.abs(p[mask] - w[mask]).max() < TOLERANCE_FLOAT32
    assert np.abs(p[~mask] - f[~mask]).max() < TOLERANCE_FLOAT32
    assert np.abs(p[~mask] - w[~mask]).max() > 1e-4  # the fill is really a cheaper solve, not a copy


def test_the_plan_is_part_of_the_request_and_recorded(tmp_path):
    s = rcwa.load_structure("cd")
    whole = _small(s)
    a = NodePlan(_checkerboard_mask(whole), (9,))
    b = NodePlan(~a.mask, (9,))
    assert len({request_key(s, whole), request_key(s, planned(whole, a)), request_key(s, planned(whole, b)),
                request_key(s, planned(whole, NodePlan(a.mask, (11,))))}) == 4
    assert "planned_nodes_sha256" not in whole.to_json()  # a whole table's key is what it was before planning
    build_table(s, planned(whole, a), tmp_path / "p.zarr", progress=False, nodes=a)
    meta = open_table(tmp_path / "p.zarr").meta
    assert meta["planned"]["exact_nodes"] == int(a.mask.sum()) and meta["planned"]["fill_orders"] == [9]
    again = build_table(s, planned(whole, a), tmp_path / "p.zarr", progress=False, nodes=a)
    assert again.cached


@pytest.mark.parametrize(("fill", "words"), [((5,), "between"), ((23,), "between"), ((8,), "odd")])
def test_bad_fill_orders_are_refused(fill, words):
    s = rcwa.load_structure("cd")
    whole = _small(s)
    with pytest.raises(UserInputError, match=words):
        planned(whole, NodePlan(_checkerboard_mask(whole), fill))


def test_a_mask_of_another_grid_is_refused():
    s = rcwa.load_structure("cd")
    whole = _small(s)
    with pytest.raises(UserInputError, match="shape"):
        planned(whole, NodePlan(np.ones((2, 2, 2), bool), (9,)))
