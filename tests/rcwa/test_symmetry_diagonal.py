"""The diagonal mirror x <-> y of a square cell (rcwa.symmetry): detection, the azimuth
fold, the physics it rests on, and tables folded by it (rcwa.table).

Tolerances:
- TOLERANCE_SYMMETRY = 1e-12: eta(m, n) at (theta, 90 - phi) against eta(n, m) at (theta,
  phi) in rcwa.solve. The swap is an exact symmetry of the truncated problem (square
  period, square truncation, a cell that maps onto itself), so only round-off separates
  them (measured 1e-15).
- TOLERANCE_NODES = 1e-10: a folded table against an unfolded one at grid nodes. Both
  store float32 roundings of float64 efficiencies that agree to 1e-15; no interpolation
  enters at nodes, so they agree unless a value straddles a float32 rounding boundary
  (a chance of about 1e-8 per value).
"""

from __future__ import annotations

import numpy as np
import pytest

import rcwa
from rcwa import symmetry
from rcwa.table import Table, angle_grid, settings_for
from tests.rcwa.diagonal_tables import DiagonalTables, build_tables

TOLERANCE_SYMMETRY = 1e-12
TOLERANCE_NODES = 1e-10
ROUND_OFF = 1e-12  # folded azimuths: a few float64 subtractions of values <= 720

GOLD2D_LIKE = """
name = "{name}"
period = [{px}, {py}]
superstrate = "air"
substrate = "air"

[[layers]]
name = "blocks"
thickness = 0.2
material = "air"
shapes = [{shapes}]
"""


def _cell(shapes: str, px: float = 1.0, py: float = 1.0, name: str = "cell") -> rcwa.Structure:
    return rcwa.Structure.from_toml_string(GOLD2D_LIKE.format(name=name, px=px, py=py, shapes=shapes), source="<test>")


def _rect(cx: float, cy: float, sx: float, sy: float) -> str:
    return f'{{ material = "gold", rect = {{ center = [{cx!r}, {cy!r}], size = [{sx!r}, {sy!r}] }} }}'


def _posts(a: float, b: float) -> str:
    """Four 0.1 um posts at (0.5 +- a, 0.5 +- b): mirrors x and y always, the diagonal iff a == b."""
    return ", ".join(_rect(0.5 + sa * a, 0.5 + sb * b, 0.1, 0.1) for sa in (-1, 1) for sb in (-1, 1))


# ---------------------------------------------------------------- detection


def test_gold2d_has_the_diagonal_mirror_and_its_table_stores_0_to_45_deg():
    s = rcwa.load_structure("gold2d")
    assert symmetry.has_diagonal_mirror(s)
    sym = symmetry.detect(s, (11, 11), (5, 5))
    assert (sym.x, sym.y, sym.diagonal) == (True, True, True) and sym.azimuth_range() == (0.0, 45.0)
    assert "diagonal x <-> y" in sym.describe()
    paper = settings_for(s, "paper")  # 2 deg steps do not divide 45: the grid goes one step past
    assert paper.phi_deg[0] == 0.0 and paper.phi_deg[-1] == 46.0 and len(paper.phi_deg) == 24


@pytest.mark.parametrize(("shapes", "period", "why"), [
    (_posts(0.25, 0.25 + 1e-6), (1.0, 1.0), "posts 1e-6 um off the diagonal"),
    (_rect(0.5, 0.5, 0.5, 0.5000001), (1.0, 1.0), "a 0.5 x 0.5000001 block"),
    (_rect(0.5, 0.5, 0.5, 0.5), (1.0, 1.0000001), "a period 1e-7 um from square"),
    (_rect(0.5, 0.5, 0.5, 0.3), (1.0, 1.0), "a rectangular block"),
])
def test_a_cell_that_only_looks_diagonal_is_not(shapes, period, why):
    """Beyond TOLERANCE_GEOMETRY (1e-9 um) a cell is not symmetric, however close; its x
    and y mirrors stay (the shapes are centred)."""
    sym = symmetry.detect(_cell(shapes, *period), (5, 5), (3, 3))
    assert sym.x and sym.y and not sym.diagonal, why
    assert sym.azimuth_range() == (0.0, 90.0)


def test_the_controls_of_those_cells_are_diagonal():
    for shapes in (_posts(0.25, 0.25), _rect(0.5, 0.5, 0.5, 0.5), '{ material = "gold", circle = { center = [0.3, 0.3], '
                   'radius = 0.2 } }'):
        assert symmetry.detect(_cell(shapes), (5, 5), (3, 3)).diagonal, shapes


def test_a_rectangular_truncation_does_not_use_the_diagonal_and_says_why():
    s = rcwa.load_structure("gold2d")
    for orders, keep in (((7, 5), (3, 3)), ((5, 5), (5, 3))):
        sym = symmetry.detect(s, orders, keep)
        assert sym.x and sym.y and not sym.diagonal and "not square" in sym.describe()
    st = settings_for(s, "draft", orders=(7, 5), keep=3, phi_step=30.0)
    assert st.phi_deg[-1] == 90.0


def test_1d_cells_never_have_the_diagonal_mirror():
    cd = rcwa.load_structure("cd")
    assert not symmetry.has_diagonal_mirror(cd) and not symmetry.detect(cd, (21,), (7,)).diagonal


def test_a_diagonal_through_the_other_crossing_of_the_mirror_lines_is_found():
    """The x and y mirror lines repeat every half period; the diagonal of this cell passes
    through (0.5, 0), not through (0, 0) (where the detection of x and y finds them): the
    rectangles at (0, 0) and (0.5, 0.5) are each other's images."""
    cell = _cell(", ".join([_rect(0.5, 0.0, 0.3, 0.3), _rect(0.0, 0.0, 0.2, 0.4), _rect(0.5, 0.5, 0.4, 0.2)]))
    assert symmetry.mirror_centres(cell) == (0.0, 0.0)
    assert symmetry.detect(cell, (5, 5), (3, 3)).diagonal
    _assert_swap_symmetry(cell, 35.0, 20.0)


# ---------------------------------------------------------------- physics


def _assert_swap_symmetry(structure: rcwa.Structure, theta: float, phi: float) -> None:
    for pol in ("s", "p"):
        a = rcwa.solve(structure, 600.0, theta, phi, (5, 5), pol).all_orders
        b = rcwa.solve(structure, 600.0, theta, 90.0 - phi, (5, 5), pol).all_orders
        index = {(int(m), int(n)): i for i, (m, n) in enumerate(zip(b["m"], b["n"], strict=True))}
        swapped = [index[int(n), int(m)] for m, n in zip(a["m"], a["n"], strict=True)]
        for name in ("R", "T"):
            np.testing.assert_allclose(np.asarray(a[name]), np.asarray(b[name])[swapped], rtol=0, atol=TOLERANCE_SYMMETRY)
            np.testing.assert_allclose(np.asarray(a[name]).mean(axis=-1), np.asarray(b[name])[swapped].mean(axis=-1),
                                       rtol=0, atol=TOLERANCE_SYMMETRY)  # unpolarized


@pytest.mark.parametrize(("theta", "phi"), [(30.0, 20.0), (55.0, 0.0), (10.0, 44.0)])
def test_gold2d_efficiencies_swap_orders_at_the_mirrored_azimuth(theta, phi):
    """eta_(m,n)(theta, phi) = eta_(n,m)(theta, 90 - phi) for s, p and unpolarized light:
    the mirror maps the plane of incidence onto the mirrored one, s onto s and p onto p.
    phi = 0 pairs a solve in mirror sectors (phi 0) with one at phi 90."""
    _assert_swap_symmetry(rcwa.load_structure("gold2d"), theta, phi)


# ---------------------------------------------------------------- the fold


SPECIAL_AZIMUTHS = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0, 360.0, -45.0, -90.0, -180.0, -360.0, 405.0, 720.0,
                    44.0, 46.0, 89.0, 91.0, -1e-20, 1e-20)


def _old_fold(phi_deg: float, mirror_x: bool, mirror_y: bool) -> tuple[float, bool, bool]:
    """rcwa.table.Table.fold_azimuth as it was before the diagonal existed (the reference an
    old table must keep being read with)."""
    phi = phi_deg % 360.0
    flip_m = flip_n = False
    if mirror_y and phi > 180.0:
        phi, flip_n = 360.0 - phi, True
    if mirror_x and mirror_y and phi > 90.0:
        phi, flip_m = 180.0 - phi, True
    if mirror_x and not mirror_y and 90.0 < phi < 270.0:
        phi, flip_m = 180.0 - phi, True
    if mirror_x and not mirror_y and phi >= 270.0:
        phi -= 360.0
    return phi, flip_m, flip_n


@pytest.mark.parametrize(("mirror_x", "mirror_y"), [(False, False), (True, False), (False, True), (True, True)])
def test_without_the_diagonal_the_fold_is_the_old_one(mirror_x, mirror_y):
    phi = np.concatenate([np.linspace(-400.0, 760.0, 2321), SPECIAL_AZIMUTHS])
    folded, flip_m, flip_n, swap = symmetry.fold_azimuths(phi, mirror_x, mirror_y)
    old = [_old_fold(float(p), mirror_x, mirror_y) for p in phi]
    np.testing.assert_allclose(folded, [o[0] for o in old], rtol=0, atol=ROUND_OFF)
    assert np.array_equal(flip_m, [o[1] for o in old]) and np.array_equal(flip_n, [o[2] for o in old]) and not swap.any()


def test_the_diagonal_fold_lands_in_0_to_45_and_its_boundaries_stay():
    phi = np.concatenate([np.linspace(-400.0, 760.0, 4641), SPECIAL_AZIMUTHS])
    folded, flip_m, flip_n, swap = symmetry.fold_azimuths(phi, True, True, True)
    assert np.all((folded >= 0.0) & (folded <= 45.0))
    # undoing the fold (the diagonal, then x, then y) gives the azimuth back, modulo 360
    back = np.where(swap, 90.0 - folded, folded)
    back = np.where(flip_m, 180.0 - back, back)
    back = np.where(flip_n, 360.0 - back, back)
    assert np.allclose(np.mod(back - phi + 180.0, 360.0) - 180.0, 0.0, atol=ROUND_OFF)
    exact = symmetry.fold_azimuths(np.array([0.0, 45.0, 90.0, 180.0, 270.0, 360.0, -90.0]), True, True, True)
    assert exact[0].tolist() == [0.0, 45.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    assert exact[3].tolist() == [False, False, True, False, True, False, True]


def test_the_stored_order_takes_the_flips_then_the_swap():
    """At phi = 120 (y: no fold; x: 180 - 120 = 60, m -> -m; diagonal: 30, swap) order
    (2, 1) is the stored (1, -2): flipped to (-2, 1), then swapped."""
    phi, flip_m, flip_n, swap = symmetry.fold_azimuths(120.0, True, True, True)
    assert float(phi) == 30.0 and bool(flip_m) and not bool(flip_n) and bool(swap)
    assert tuple(int(v) for v in symmetry.stored_order(2, 1, flip_m, flip_n, swap)) == (1, -2)


def test_an_azimuth_step_that_does_not_divide_the_range_ends_one_step_past_it():
    assert angle_grid(2.0, 0.0, 45.0, "phi", cover=True)[-2:] == (44.0, 46.0)
    assert angle_grid(15.0, 0.0, 45.0, "phi", cover=True)[-1] == 45.0
    assert angle_grid(7.0, 0.0, 90.0, "phi", cover=True)[-1] == 91.0
    assert angle_grid(7.0, 0.0, 90.0, "theta")[-1] == 84.0  # polar angles never pass 90


# ---------------------------------------------------------------- tables


@pytest.fixture(scope="module")
def tables(tmp_path_factory) -> DiagonalTables:
    return build_tables(tmp_path_factory.mktemp("diagonal"), pytest.MonkeyPatch.context)


def test_the_folded_tables_metadata(tables):
    sym = tables.folded.meta["symmetry"]
    assert sym["mirror_diagonal"] and sym["phi_range_deg"] == [0.0, 45.0] and tables.folded.phi_deg[-1] == 45.0
    assert "mirror_diagonal" not in tables.old.meta["symmetry"] and tables.old.mirrors == (True, True, False)
    assert tables.old.phi_deg[-1] == 90.0


@pytest.mark.parametrize("which", ["folded", "old"])
def test_a_folded_table_reads_as_the_unfolded_one_at_every_node(tables, which):
    """Every order at every stored azimuth of the unfolded table (0-345 deg), read through
    Table.fold_azimuth and stored_index: the table folded by the diagonal, and the
    old-format one (x and y only, no mirror_diagonal key) read as before."""
    table: Table = getattr(tables, which)
    full = tables.unfolded
    assert table.orders == full.orders
    for k, phi in enumerate(full.phi_deg):
        folded, flip_m, flip_n, swap = table.fold_azimuth(float(phi))
        assert not (swap and which == "old")
        node = int(np.argmin(np.abs(table.phi_deg - folded)))
        assert abs(table.phi_deg[node] - folded) < ROUND_OFF
        for q, (m, n) in enumerate(full.orders):
            stored = table.stored_index(m, n, flip_m, flip_n, swap)
            for name in ("R", "T"):
                np.testing.assert_allclose(full.arrays[name][:, :, k, q], table.arrays[name][:, :, node, stored],
                                           rtol=0, atol=TOLERANCE_NODES, err_msg=f"{name} ({m}, {n}) at phi {phi}")


def test_rcwa_info_shows_the_diagonal_and_the_note_of_an_unused_one(tables, tmp_path):
    from rcwa.table import build_table
    from workbench.catalog import format_table_info, table_info

    assert "symmetry      mirror x and y and diagonal x <-> y; azimuths stored 0-45 deg" in format_table_info(
        table_info(tables.folded.path))
    assert "symmetry      mirror x and y; azimuths stored 0-90 deg\n" in format_table_info(table_info(tables.old.path))
    s = rcwa.load_structure("gold2d")
    rectangular = settings_for(s, "draft", wavelengths="550", theta_step=90.0, phi_step=90.0, orders=(3, 1), keep=(3, 1))
    build_table(s, rectangular, tmp_path / "r.zarr", progress=False, threads=1)
    text = format_table_info(table_info(tmp_path / "r.zarr"))
    assert "azimuths stored 0-90 deg (the cell's diagonal mirror x <-> y is not used: orders 3x1, kept orders 3x1 not " \
           "square)" in text
