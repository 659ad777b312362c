"""The kernel lookup's fold (renderer.efficiency, Dr.Jit) against rcwa.symmetry.fold_azimuths
(numpy), and a table folded by gold2d's diagonal mirror read through the kernel.

Tolerances:
- ROUND_OFF_FLOAT32 = 1e-4 deg: the kernel folds in float32; the azimuths tested are
  multiples of 1/8 deg below 1024 deg (exact in float32, and so are the folds' sums), so
  the flips and swaps must agree exactly and the folded azimuths to float32 round-off.
- At grid nodes: TOLERANCE_NODES = 1e-10 (the folded and unfolded tables store float32
  roundings of float64 efficiencies equal to 1e-15; tests/rcwa/test_symmetry_diagonal.py
  compares the stored values so), plus what the kernel's own float32 index arithmetic
  adds: it computes (phi - start) / step as a product with the step's float32 reciprocal,
  so at a node (45 deg on a 15 deg grid: 3.0000002) the neighbour gets a weight of up to
  a float32 ulp of the index (below 8 here: 4.8e-7; KERNEL_FRACTION_ERROR = 1e-6) times
  the largest change between neighbouring nodes. A wrong order or azimuth would be off
  by the efficiencies themselves (1e-2 here).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rcwa import symmetry
from tests.rcwa.diagonal_tables import DiagonalTables, build_tables

ROUND_OFF_FLOAT32 = 1e-4
TOLERANCE_NODES = 1e-10
KERNEL_FRACTION_ERROR = 1e-6
MIRRORS = [(False, False, False), (True, False, False), (False, True, False), (True, True, False), (True, True, True)]


def _lookup(mirror_x: bool, mirror_y: bool, diagonal: bool, keep: int = 5):
    import mitsuba as mi

    from renderer.efficiency import EfficiencyLookup

    ms, ns = np.meshgrid(np.arange(keep) - keep // 2, np.arange(keep) - keep // 2, indexing="ij")
    axis = (0.0, 1.0, 2)
    return EfficiencyLookup(mi.Float(np.zeros(8 * ms.size, np.float32)), axis, axis, axis, ms.ravel(), ns.ravel(),
                            mirror_x, mirror_y, diagonal)


@pytest.mark.parametrize(("mirror_x", "mirror_y", "diagonal"), MIRRORS)
def test_the_kernels_fold_is_rcwa_symmetrys(mitsuba_variant, mirror_x, mirror_y, diagonal):
    import mitsuba as mi

    special = [0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0, 360.0, -45.0, -90.0, -180.0, -270.0, -360.0, 405.0, 720.0]
    phi = np.concatenate([np.arange(-720.0, 1000.0, 0.125), special]).astype(np.float32)
    got = [np.array(v) for v in _lookup(mirror_x, mirror_y, diagonal).fold(mi.Float(phi))]
    expected = symmetry.fold_azimuths(phi.astype(float), mirror_x, mirror_y, diagonal)
    np.testing.assert_allclose(got[0], expected[0], rtol=0, atol=ROUND_OFF_FLOAT32)
    for name, g, e in zip(("flip_m", "flip_n", "swap"), got[1:], expected[1:], strict=True):
        assert np.array_equal(g, e), name


def test_the_kernels_index_mapping_is_rcwa_symmetrys_stored_order(mitsuba_variant):
    """Every kept order under every combination of flips and swap: the kernel's index is
    that of rcwa.symmetry.stored_order (the flips first, then the swap)."""
    import mitsuba as mi

    look = _lookup(True, True, True)
    orders = list(zip(look.orders_m.tolist(), look.orders_n.tolist(), strict=True))
    k = np.arange(look.order_count)
    for flip_m, flip_n, swap in itertools.product((False, True), repeat=3):
        flags = [mi.Bool(np.full(k.size, f)) for f in (flip_m, flip_n, swap)]
        got = np.array(look._flipped_index(mi.UInt32(k), *flags))
        sm, sn = symmetry.stored_order(look.orders_m, look.orders_n, flip_m, flip_n, swap)
        assert got.tolist() == [orders.index((int(a), int(b))) for a, b in zip(sm, sn, strict=True)]


@pytest.fixture(scope="module")
def tables(tmp_path_factory) -> DiagonalTables:
    return build_tables(tmp_path_factory.mktemp("diagonal"), pytest.MonkeyPatch.context)


@pytest.mark.parametrize("which", ["folded", "old"])
@pytest.mark.parametrize("array", ["R", "T"])
def test_the_kernel_reads_a_folded_table_as_the_unfolded_one(mitsuba_variant, tables, which, array):
    """Every kept order at every node of the unfolded table (azimuths 0-345 deg, and the
    same shifted by -360 and +360), through EfficiencyLookup.eval on the table folded by
    the diagonal and on the old-format one (no mirror_diagonal key: x and y only)."""
    import mitsuba as mi

    from renderer.efficiency import EfficiencyLookup

    full = tables.unfolded
    look = EfficiencyLookup.from_table(getattr(tables, which), array)
    assert look.mirror_diagonal == (which == "folded")
    values = full.arrays[array][..., full.meta["pol_names"].index("unpolarized")]  # (W, Th, Ph, K)
    w, t, p, k = np.meshgrid(*(np.arange(n) for n in values.shape), indexing="ij")
    w, t, p, k = w.ravel(), t.ravel(), p.ravel(), k.ravel()
    expected = values[w, t, p, k]
    steps = max(float(np.abs(np.diff(values, axis=axis)).max()) for axis in (1, 2))
    tolerance = TOLERANCE_NODES + KERNEL_FRACTION_ERROR * steps
    for turn in (0.0, -360.0, 360.0):
        got = np.array(look.eval(mi.UInt32(k), mi.Float(full.wavelengths_nm[w]), mi.Float(full.theta_deg[t]),
                                 mi.Float(full.phi_deg[p] + turn)))
        np.testing.assert_allclose(got, expected, rtol=0, atol=tolerance, err_msg=f"azimuths shifted by {turn}")
