"""Efficiency tables: values, symmetry, resume after SIGKILL, corruption, cache, errors.

Tolerances: tables store float32, so comparisons with float64 solves use
TOLERANCE_FLOAT32 = 1e-6 absolute (efficiencies are <= 1; float32 rounding is 6e-8).
A resumed build must equal an uninterrupted one exactly (same code, same inputs).
"""

import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import rcwa
from rcwa.table import build_table, open_table, settings_for
from tests.rcwa.helpers import damage_chunk
from workbench.core.errors import UserInputError

# Only a guard against a hang: the child reaches the state it is waited for in seconds; the wait
# ends on that state, never on the clock (issue 23: a loaded machine may be ten times slower).
HANG_GUARD_S = 900.0

TOLERANCE_FLOAT32 = 1e-6


def _small(structure, **kw):
    args = dict(wavelengths="450:650:3", theta_step=30.0, phi_step=30.0, orders=21, keep=7)
    args.update(kw)
    return settings_for(structure, "draft", **args)


def test_table_equals_direct_solves(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s, pol="all")
    build_table(s, st, tmp_path / "t.zarr", progress=False)
    t = open_table(tmp_path / "t.zarr")
    assert set(t.arrays) == {"R"}  # aluminium substrate: nothing is transmitted
    for i, wl in enumerate(st.wavelengths_nm):
        for j, th in enumerate(st.theta_deg[:-1]):  # the last row is the grazing limit
            for k, ph in enumerate(st.phi_deg):
                direct = {pol: rcwa.solve(s, wl, th, ph, 21, pol) for pol in ("s", "p")}
                for q, (m, _) in enumerate(t.orders):
                    by_pol = [direct[p].all_orders["R"][list(direct[p].all_orders["m"]).index(m), "sp".index(p)] for p in "sp"]
                    assert t.arrays["R"][i, j, k, q, :2] == pytest.approx(by_pol, abs=TOLERANCE_FLOAT32)
                    assert t.arrays["R"][i, j, k, q, 2] == pytest.approx(np.mean(by_pol), abs=TOLERANCE_FLOAT32)


def test_symmetry_reduced_equals_full_grid(tmp_path):
    s = rcwa.load_structure("cd")
    reduced = _small(s)
    full = _small(s, use_symmetry=False)
    assert reduced.phi_deg[-1] == 90.0 and full.phi_deg[-1] > 300.0
    build_table(s, reduced, tmp_path / "r.zarr", progress=False)
    build_table(s, full, tmp_path / "f.zarr", progress=False)
    r, f = open_table(tmp_path / "r.zarr"), open_table(tmp_path / "f.zarr")
    orders = r.orders
    for k, phi in enumerate(f.phi_deg):
        folded, flip_m, flip_n, _ = r.fold_azimuth(phi)  # the CD has no diagonal mirror: no swap
        kr = int(np.argmin(np.abs(r.phi_deg - folded)))
        assert abs(r.phi_deg[kr] - folded) < 1e-9
        for q, (m, n) in enumerate(orders):
            qr = orders.index((-m if flip_m else m, -n if flip_n else n))
            np.testing.assert_allclose(f.arrays["R"][:, :, k, q], r.arrays["R"][:, :, kr, qr], atol=TOLERANCE_FLOAT32)


def test_both_sides_of_a_z_symmetric_see_through_grating(tmp_path):
    s = rcwa.load_structure("gold2d")  # air on both sides, the block is symmetric in z
    st = settings_for(s, "draft", wavelengths="550", theta_step=45.0, phi_step=45.0, orders=5, keep=3, both_sides=True)
    build_table(s, st, tmp_path / "g.zarr", progress=False)
    t = open_table(tmp_path / "g.zarr")
    assert {"R", "T", "R_below", "T_below"} <= set(t.arrays)
    np.testing.assert_allclose(t.arrays["R_below"], t.arrays["R"], atol=TOLERANCE_FLOAT32)
    np.testing.assert_allclose(t.arrays["T_below"], t.arrays["T"], atol=TOLERANCE_FLOAT32)


def test_sigkill_then_resume_equals_uninterrupted(tmp_path):
    out = tmp_path / "k.zarr"
    cmd = [sys.executable, "-m", "workbench.cli", "rcwa", "table", "cd", "--out", str(out), "--preset", "draft",
           "--wavelengths", "400:700:8", "--orders", "41", "--theta-step", "3", "--phi-step", "5", "--quiet", "--threads", "1"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.time() + HANG_GUARD_S
    while time.time() < deadline and proc.poll() is None:
        try:
            if len(json.loads((out / "progress.json").read_text())) >= 2:
                break
        except (OSError, ValueError):
            pass
        time.sleep(0.01)
    assert proc.poll() is None, "the build finished before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    finished_before = len(json.loads((out / "progress.json").read_text()))
    assert 2 <= finished_before < 8
    with pytest.raises(UserInputError, match="unfinished"):
        open_table(out)
    resumed = subprocess.run(cmd, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    assert f"({finished_before} resumed)" in resumed.stdout
    s = rcwa.load_structure("cd")
    st = settings_for(s, "draft", wavelengths="400:700:8", orders=41, theta_step=3.0, phi_step=5.0)
    build_table(s, st, tmp_path / "clean.zarr", progress=False, threads=1)
    assert np.array_equal(open_table(out).arrays["R"], open_table(tmp_path / "clean.zarr").arrays["R"])


def _chunk_files(path):
    return sorted(p for p in (path / "R" / "c").rglob("*") if p.is_file())


@pytest.mark.parametrize("damage", ["flip a byte", "truncate", "delete"])
def test_damaged_table_is_a_clear_error(tmp_path, damage):
    s = rcwa.load_structure("cd")
    out = tmp_path / "d.zarr"
    build_table(s, _small(s), out, progress=False)
    chunk = _chunk_files(out)[1]
    damage_chunk(chunk, damage)
    with pytest.raises(UserInputError) as err:
        open_table(out)
    assert str(out) in str(err.value)


def test_same_request_is_served_from_the_cache(tmp_path):
    s = rcwa.load_structure("cd")
    st = _small(s)
    first = build_table(s, st, tmp_path / "c.zarr", progress=False)
    again = build_table(s, st, tmp_path / "c.zarr", progress=False)
    assert not first.cached and again.cached and again.chunks_computed == 0
    with pytest.raises(UserInputError, match="different table"):
        build_table(s, _small(s, keep=5), tmp_path / "c.zarr", progress=False)


@pytest.mark.parametrize("args, field", [
    (["--wavelengths", "700:400:3"], "--wavelengths"),
    (["--wavelengths", "400:700:0"], "--wavelengths"),
    (["--theta-step", "0"], "--theta-step"),
    (["--phi-step", "-5"], "--phi-step"),
    (["--orders", "21", "--keep-orders", "23"], "--keep-orders"),
    (["--orders", "20"], "--orders"),
    (["--keep-orders", "4"], "--keep-orders"),
    (["--theta-range", "50,20"], "--theta-range"),
    (["--phi-range", "0,120"], "--phi-range"),  # the CD's stored azimuths are 0-90 (mirror symmetric)
])
def test_bad_table_arguments(tmp_path, capsys, args, field):
    from workbench.cli import main

    code = main(["rcwa", "table", "cd", "--out", str(tmp_path / "x.zarr"), "--preset", "draft", "--quiet", *args])
    err = capsys.readouterr().err
    assert code == 2 and field in err and "Traceback" not in err
    assert not (tmp_path / "x.zarr").exists()


def test_dask_local_cluster_equals_local_run(tmp_path):
    """Two worker processes on loopback give exactly the local result."""
    from workbench.core.executor import DaskExecutor

    s = rcwa.load_structure("cd")
    st = _small(s)
    local = build_table(s, st, tmp_path / "local.zarr", progress=False, threads=1)
    with DaskExecutor(workers=2) as executor:
        report = build_table(s, st, tmp_path / "dask.zarr", progress=False, executor=executor)
    assert report.chunks_computed == len(st.wavelengths_nm)
    # The workers' sweep statistics come back too (same blocks, so the same counts).
    assert (report.eigen_solves, report.eigen_refined) == (local.eigen_solves, local.eigen_refined)
    assert report.eigen_solves > 0
    assert np.array_equal(open_table(tmp_path / "dask.zarr").arrays["R"], open_table(tmp_path / "local.zarr").arrays["R"])


def test_unreachable_scheduler_is_a_clear_error(tmp_path, capsys):
    from workbench.cli import main

    code = main(["rcwa", "table", "cd", "--out", str(tmp_path / "x.zarr"), "--preset", "draft", "--quiet",
                 "--scheduler", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 2 and "--scheduler" in err and "Traceback" not in err


def test_sub_domain_is_the_same_as_the_full_grid_there(tmp_path):
    s = rcwa.load_structure("cd")
    full = _small(s, theta_step=10.0, phi_step=15.0)
    part = _small(s, theta_step=10.0, phi_step=15.0, theta_range=(20.0, 50.0), phi_range=(30.0, 60.0))
    assert part.theta_deg == (20.0, 30.0, 40.0, 50.0) and part.phi_deg == (30.0, 45.0, 60.0)
    build_table(s, full, tmp_path / "full.zarr", progress=False)
    build_table(s, part, tmp_path / "part.zarr", progress=False)
    f, p = open_table(tmp_path / "full.zarr"), open_table(tmp_path / "part.zarr")
    np.testing.assert_array_equal(p.arrays["R"], f.arrays["R"][:, 2:6, 2:5])
