"""A table's own truncation error (rcwa.table.truncation): what it records, that it can be
recomputed exactly, that it shrinks as the table's truncation grows, that it survives a
resume, and that `workbench rcwa info` prints it (or says an old table lacks it).

Tolerances: the record compares the float32 values a table stores, so an independent
recomputation by the same sweep (same nodes, same orders, one thread) must give the same
number exactly; one by single solves (rcwa.solve, which agrees with a sweep to 1e-13,
tests/rcwa/test_sweep.py) agrees to TOLERANCE_FLOAT32 = 1e-6 (two float32 roundings of
values <= 1 are 1.2e-7).
"""

import json
from typing import Any

import numpy as np
import pytest
import zarr

import rcwa
from rcwa.convergence import metal_grating
from rcwa.sweep import sweep_directions
from rcwa.table import NodePlan, build_table, open_table, planned, read_table_metadata, settings_for
from rcwa.table.compute import clamped
from tests.rcwa.helpers import lamellar
from workbench.cli import main

TOLERANCE_FLOAT32 = 1e-6


def _small(structure, **kw):
    args: dict[str, Any] = dict(wavelengths="500,600", theta_step=30.0, phi_step=30.0, orders=21, keep=7)
    args.update(kw)
    return settings_for(structure, "draft", **args)


def _stored(sweep, pol: str) -> dict[str, np.ndarray]:
    """A sweep's R and T as a table stores them: (direction, order, pol), float32."""
    pick = {"unpolarized": lambda v: v.mean(axis=-1, keepdims=True), "s": lambda v: v[..., :1], "p": lambda v: v[..., 1:],
            "all": lambda v: np.concatenate([v, v.mean(axis=-1, keepdims=True)], axis=-1)}[pol]
    return {"R": pick(sweep.R).astype(np.float32), "T": pick(sweep.T).astype(np.float32)}


def _recompute(structure, settings, wavelength, nodes, orders_a, orders_b, rule_a, rule_b, arrays) -> float:
    theta = clamped([t for t, _ in nodes])
    phi = np.array([p for _, p in nodes])
    a = _stored(sweep_directions(structure, wavelength, theta, phi, orders_a, keep=settings.keep,
                                 factorization=rule_a, threads=1), settings.pol)
    b = _stored(sweep_directions(structure, wavelength, theta, phi, orders_b, keep=settings.keep,
                                 factorization=rule_b, threads=1), settings.pol)
    return max(float(np.max(np.abs(a[n].astype(float) - b[n].astype(float)))) for n in arrays)


def test_recorded_truncation_error_is_an_independent_recomputation(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s, pol="all")
    build_table(s, st, tmp_path / "t.zarr", progress=False)
    meta = read_table_metadata(tmp_path / "t.zarr")
    table = open_table(tmp_path / "t.zarr")
    records = meta["truncation_error"]
    assert sorted(records, key=int) == ["0", "1"]
    for i, wl in enumerate(st.wavelengths_nm):
        r = records[str(i)]
        nodes = [tuple(n) for n in r["nodes"]]
        assert r["wavelength_nm"] == wl and r["rule"] == "li" and len(nodes) == 1  # 16 nodes: one sampled
        worst = r["truncation"]
        assert worst["lower_orders"] == [11] and "factorization" not in r  # 1D: Li's rule is the normal-vector method
        assert worst["max_difference"] == _recompute(s, st, wl, nodes, 21, 11, "li", "li", meta["arrays"])
        # the same number from single solves, at the recorded order and polarization
        m, pol = worst["order"][0], worst["pol"]
        values = []
        for n_orders in (21, 11):
            res = rcwa.solve(s, wl, worst["theta_deg"], worst["phi_deg"], n_orders)  # all_orders: s and p columns
            ms = list(res.all_orders["m"])
            by = res.all_orders[worst["array"]][ms.index(m)]
            values.append(float(np.mean(by)) if pol == "unpolarized" else float(by["sp".index(pol)]))
        assert worst["max_difference"] == pytest.approx(abs(values[0] - values[1]), abs=TOLERANCE_FLOAT32)
        # the sampled node's values at the table's orders are the table's own
        j, k = list(st.theta_deg).index(worst["theta_deg"]), list(st.phi_deg).index(worst["phi_deg"])
        q = table.orders.index((m, 0))
        assert table.arrays[worst["array"]][i, j, k, q, meta["pol_names"].index(pol)] == pytest.approx(
            values[0], abs=TOLERANCE_FLOAT32)


def test_a_2d_table_records_the_other_factorization_rule(tmp_path):
    s = rcwa.load_structure("gold2d")  # rectangles: Li's rule [Li 1997]; compared with the normal-vector method
    st = settings_for(s, "draft", wavelengths="550", theta_step=45.0, phi_step=45.0, orders=5, keep=3)
    build_table(s, st, tmp_path / "g.zarr", progress=False)
    meta = read_table_metadata(tmp_path / "g.zarr")
    r = meta["truncation_error"]["0"]
    nodes = [tuple(n) for n in r["nodes"]]
    assert r["rule"] == "li" and r["factorization"]["other_rule"] == "nv" and r["truncation"]["lower_orders"] == [3, 3]
    assert r["factorization"]["max_difference"] == _recompute(s, st, 550.0, nodes, (5, 5), (5, 5), "li", "nv",
                                                              meta["arrays"])
    assert r["truncation"]["max_difference"] == _recompute(s, st, 550.0, nodes, (5, 5), (3, 3), "li", "li",
                                                           meta["arrays"])
    # the point: at these truncations the gold block is far from converged (> 1e-3 both ways)
    assert r["truncation"]["max_difference"] > 1e-3 and r["factorization"]["max_difference"] > 1e-3


@pytest.mark.parametrize("structure, pol, wavelength", [(lamellar(), "all", "633"), (metal_grating(), "p", "1000")],
                         ids=["glass-lamellar", "metal-lamellar-TM"])
def test_the_recorded_error_shrinks_as_the_table_retains_more_orders(tmp_path, structure, pol, wavelength):
    """One node (theta 30 deg, phi 0; for the metal, the Littrow mount of [Li 1993] /
    [Granet 1996]). RCWA under Li's rule converges algebraically, error ~ N^-p with p >= 1
    ([Li 1996, Fig. 3]), so the difference between N and about N/2 should fall by at
    least (11/41)^1 = 0.27 from N = 11 to N = 41; measured: 0.011 (glass), 0.043 (metal).
    For the dielectric grating, whose convergence is monotone here, the estimate at 41
    orders also bounds the true error against a 201-order solve (whose own error, ~1e-5
    by this estimate, is the slack)."""
    recorded = {}
    for n in (11, 41):
        st = settings_for(structure, "draft", wavelengths=wavelength, theta_range=(30, 30), phi_range=(0, 0), orders=n,
                          keep=3, pol=pol)
        build_table(structure, st, tmp_path / f"{n}.zarr", progress=False)
        recorded[n] = read_table_metadata(tmp_path / f"{n}.zarr")["truncation_error"]["0"]["truncation"]
    assert recorded[11]["lower_orders"] == [5] and recorded[41]["lower_orders"] == [21]
    assert recorded[41]["max_difference"] < 0.27 * recorded[11]["max_difference"], recorded
    if structure.dimension == 1 and pol == "all":
        wl = float(wavelength)
        true_error = 0.0
        for p in ("s", "p"):
            fine, table = rcwa.solve(structure, wl, 30.0, 0.0, 201, p), rcwa.solve(structure, wl, 30.0, 0.0, 41, p)
            for m in (-1, 0, 1):
                for a in ("R", "T"):
                    pick = [list(r.all_orders["m"]).index(m) for r in (fine, table)]
                    true_error = max(true_error, abs(fine.all_orders[a][pick[0], "sp".index(p)]
                                                     - table.all_orders[a][pick[1], "sp".index(p)]))
        assert true_error <= recorded[41]["max_difference"] + 1e-5


def test_a_planned_table_samples_only_nodes_solved_with_its_orders(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s, wavelengths="500")
    mask = np.zeros((1, len(st.theta_deg), len(st.phi_deg)), bool)
    mask[0, 1, 2] = True
    nodes = NodePlan(mask, (11,))
    build_table(s, planned(st, nodes), tmp_path / "p.zarr", progress=False, nodes=nodes)
    r = read_table_metadata(tmp_path / "p.zarr")["truncation_error"]["0"]
    assert r["nodes"] == [[st.theta_deg[1], st.phi_deg[2]]]


def strip_records(path) -> None:
    """Make ``path`` look like a table written before tables recorded their truncation error."""
    group = zarr.open_group(str(path), mode="a")
    attrs = dict(group.attrs)
    del attrs["truncation_error"]
    group.attrs.clear()
    group.attrs.update(attrs)
    progress = json.loads((path / "progress.json").read_text())
    for record in progress.values():
        del record["truncation"]
    (path / "progress.json").write_text(json.dumps(progress))


def test_a_resumed_build_keeps_and_completes_the_records(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s, wavelengths="450:650:3")
    out = tmp_path / "r.zarr"
    build_table(s, st, out, progress=False)
    before = read_table_metadata(out)["truncation_error"]
    strip_records(out)  # chunks from an older build ...
    group = zarr.open_group(str(out), mode="a")
    group.attrs["complete"] = False
    progress = json.loads((out / "progress.json").read_text())
    del progress["2"]  # ... and one chunk still to compute
    (out / "progress.json").write_text(json.dumps(progress))
    report = build_table(s, st, out, progress=False)
    assert report.chunks_computed == 1 and report.chunks_reused == 2
    after = read_table_metadata(out)["truncation_error"]
    assert sorted(after) == ["0", "1", "2"]
    for record in (*before.values(), *after.values()):
        assert record.pop("seconds") > 0  # the sample's time, which differs from run to run
    assert after == before  # deterministic: the same nodes, the same numbers


def test_rcwa_info_prints_the_truncation_error_or_says_it_is_not_recorded(tmp_path, capsys):
    out = tmp_path / "i.zarr"
    assert main(["rcwa", "table", "cd", "--out", str(out), "--preset", "draft", "--wavelengths", "500,600",
                 "--theta-step", "30", "--phi-step", "30", "--orders", "21", "--keep-orders", "7", "--quiet"]) == 0
    built = capsys.readouterr().out
    records = read_table_metadata(out)["truncation_error"]
    worst = max(records.values(), key=lambda r: r["truncation"]["max_difference"])["truncation"]
    assert f"largest vs lower truncation: {worst['max_difference']:.2e} (11)" in built, built  # the build says it too
    assert main(["rcwa", "info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "truncation    error recorded at 2 of 2 wavelengths" in text, text
    assert f"largest vs lower truncation: {worst['max_difference']:.2e} (11)" in text, text
    for r in records.values():
        assert f"{r['wavelength_nm']:g} nm: vs lower: {r['truncation']['max_difference']:.2e} (11)" in text, text
    assert main(["rcwa", "info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["truncation_error"]["truncation"]["max_difference"] == worst["max_difference"]
    strip_records(out)
    assert main(["rcwa", "info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "truncation    error not recorded" in text and "integrity     intact" in text, text
    open_table(out)  # an old table still reads
