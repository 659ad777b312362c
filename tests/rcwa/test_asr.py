"""Adaptive spatial resolution (rcwa.asr, issue 29 item 2) against the core and analytic limits.

* Without a stretch (eta = 0) the stretched-coordinate solver is Li's rule itself: every
  order's R and T equal the C++ core's to round-off (measured 1e-14; bar 1e-10), on a cell
  with no mirror (two off-centre rectangles, two patterned layers and a uniform one, in
  conical incidence), so the order sign, the convolution matrices, the permeability's place
  in P and Q and the ETM stack are all the core's.
* With a stretch, a patterned layer whose two materials are equal is a uniform film, whose
  R and T are Airy's (the core's uniform layer: no eigen-solve, no truncation). The stretch
  makes the film an inhomogeneous anisotropic medium and the half-spaces' plane waves a
  truncated change of basis, so agreement tests both; it converges with N (measured at
  eta = 0.9: 1.7e-3 at N = 5, 3.8e-5 at 9, 4e-6 at 13; bar 5e-5 at 13, 1e-4 at 9).
* Energy: a lossless dielectric block conserves energy only as the truncation converges
  (measured |1 - R - T| 0.13 at N = 5, 0.0095 at 9, 1.0e-3 at 13, 5e-5 at 17; bar 2e-4 at 17
  and a fall by 10x from 9 to 17).
* The point of it: gold2d's T(0,0) at 550 nm, normal incidence (Li's rule's slowest
  quantity, docs/gold2d_convergence.md) is within 0.002 of Li's own extrapolated limit
  (0.0753 +- 0.0064, N up to 61) at 17 x 17 with ASR (measured 0.0748) where Li's rule at
  17 x 17 is 0.011 off (0.0645; at 61 x 61 still 0.002).
* The normal-vector rule in the same coordinates (``rule="nv"``): without a stretch it is the
  core's NV rule order by order (measured 1e-14; bar 1e-10, on the asymmetric cell). With
  it, gold2d at 650 nm, normal incidence, where the uniform NV rule drifts away from the
  other formulations (T_total 0.53, 0.45, 0.41 at N = 15, 25, 35 against Li's and ASR's
  0.614: docs/gold2d_convergence.md), T_total at 17 x 17 is within 0.04 of Li's extrapolated
  0.6143 (measured 0.585) and T(0,0) within 0.003 of Li's 0.0238 (measured 0.0259), where
  the uniform rule at 17 is 0.1 and 0.15 off.
* Bad input: a circle, a 1D structure, a stretch outside [0, 1) and an unknown rule name the
  field; the 2D study leaves both ASR rules out for a cell with a circle.
"""

import numpy as np
import pytest

import rcwa
from rcwa.asr import solve_asr
from rcwa.structure import Structure, load_structure
from workbench.core.errors import UserInputError

ASYMMETRIC = """
name = "asymmetric"
period = [1.0, 0.8]
superstrate = "air"
substrate = 1.5
[[layers]]
thickness = 0.15
material = "air"
shapes = [ { material = { n = 0.5, k = 2.5 }, rect = { center = [0.3, 0.45], size = [0.35, 0.3] } },
           { material = 2.0, rect = { center = [0.7, 0.2], size = [0.2, 0.25] } } ]
[[layers]]
thickness = 0.1
material = 1.3
[[layers]]
thickness = 0.2
material = 1.8
shapes = [ { material = "air", rect = { center = [0.55, 0.6], size = [0.4, 0.2] } } ]
"""
FILM = """
name = "film"
period = [1.0, 0.8]
superstrate = "air"
substrate = 1.5
[[layers]]
thickness = 0.2
material = { n = 2.0, k = 0.3 }
shapes = [ { material = { n = 2.0, k = 0.3 }, rect = { center = [0.3, 0.5], size = [0.35, 0.3] } } ]
"""
BLOCK = """
name = "block"
period = [1.0, 1.0]
superstrate = "air"
substrate = "air"
[[layers]]
thickness = 0.6
material = "air"
shapes = [ { material = 2.0, rect = { center = [0.4, 0.55], size = [0.5, 0.35] } } ]
"""
LI_LIMIT_T00 = 0.0753  # gold2d, 550 nm, normal incidence: Li's rule extrapolated (docs/gold2d_convergence.md)
LI_LIMIT_650 = {"T_total": 0.6143, "T00": 0.0238}  # gold2d, 650 nm, normal incidence: the same table


def _core(structure: Structure, wl: float, theta: float, phi: float, n: int,
          rule: str = "li") -> tuple[np.ndarray, np.ndarray]:
    solves = [rcwa.solve(structure, wl, theta, phi, (n, n), pol, rule).all_orders for pol in ("s", "p")]
    R = np.stack([s["R"][:, i] for i, s in enumerate(solves)], axis=1)
    T = np.stack([s["T"][:, i] for i, s in enumerate(solves)], axis=1)
    return R, T


def test_without_a_stretch_it_is_the_cores_li_rule_order_by_order():
    structure = Structure.from_toml_string(ASYMMETRIC)
    for n in (5, 7):
        ours = solve_asr(structure, 600.0, 25.0, 35.0, n, eta=0.0)
        R, T = _core(structure, 600.0, 25.0, 35.0, n)
        assert np.max(np.abs(ours.R - R)) < 1e-10
        assert np.max(np.abs(ours.T - T)) < 1e-10
        assert T.sum() > 0.1 and R.sum() > 0.01  # the comparison is not of zeros


def test_without_a_stretch_its_nv_rule_is_the_cores_nv_rule_order_by_order():
    structure = Structure.from_toml_string(ASYMMETRIC)
    ours = solve_asr(structure, 600.0, 25.0, 35.0, 5, eta=0.0, rule="nv")
    R, T = _core(structure, 600.0, 25.0, 35.0, 5, rule="nv")
    assert np.max(np.abs(ours.R - R)) < 1e-10
    assert np.max(np.abs(ours.T - T)) < 1e-10
    li = solve_asr(structure, 600.0, 25.0, 35.0, 5, eta=0.0)
    assert np.max(np.abs(ours.T - li.T)) > 1e-3  # the rule is in use: NV and Li differ at this truncation


def test_the_stretch_converges_the_nv_rule_at_650_nm_where_uniform_nv_drifts():
    gold2d = load_structure("gold2d")
    zero = lambda result: result.T[(result.m == 0) & (result.n == 0), 0][0]  # noqa: E731
    stretched = solve_asr(gold2d, 650.0, 0.0, 0.0, 17, rule="nv")
    uniform = solve_asr(gold2d, 650.0, 0.0, 0.0, 17, eta=0.0, rule="nv")
    assert abs(stretched.T[:, 0].sum() - LI_LIMIT_650["T_total"]) < 0.04
    assert abs(zero(stretched) - LI_LIMIT_650["T00"]) < 0.003
    assert abs(uniform.T[:, 0].sum() - LI_LIMIT_650["T_total"]) > 0.06  # the comparison: uniform NV at 17
    assert abs(zero(uniform) - LI_LIMIT_650["T00"]) > 0.1


def test_a_stretched_uniform_film_converges_to_airys_film():
    structure = Structure.from_toml_string(FILM)
    R, T = _core(structure, 600.0, 30.0, 20.0, 3)  # uniform: the core's result does not depend on N
    errors = {}
    for n in (9, 13):
        ours = solve_asr(structure, 600.0, 30.0, 20.0, n, eta=0.9)
        errors[n] = max(np.max(np.abs(ours.R.sum(axis=0) - R.sum(axis=0))), np.max(np.abs(ours.T.sum(axis=0) - T.sum(axis=0))))
    assert errors[9] < 1e-4
    assert errors[13] < 5e-5


def test_a_stretched_lossless_block_conserves_energy_as_it_converges():
    structure = Structure.from_toml_string(BLOCK)
    defect = {n: np.max(np.abs(1.0 - solve_asr(structure, 550.0, 25.0, 35.0, n, eta=0.9).R.sum(axis=0)
                                - solve_asr(structure, 550.0, 25.0, 35.0, n, eta=0.9).T.sum(axis=0)))
              for n in (9, 17)}
    assert defect[17] < 2e-4
    assert defect[17] < defect[9] / 10


def test_the_stretch_converges_gold2ds_zero_order_faster_than_li():
    gold2d = load_structure("gold2d")
    zero = lambda result: result.T[(result.m == 0) & (result.n == 0), 0][0]  # noqa: E731
    asr = zero(solve_asr(gold2d, 550.0, 0.0, 0.0, 17))
    li = zero(solve_asr(gold2d, 550.0, 0.0, 0.0, 17, eta=0.0))
    assert abs(asr - LI_LIMIT_T00) < 0.002
    assert abs(li - LI_LIMIT_T00) > 0.008  # the comparison: Li's rule at the same truncation


@pytest.mark.parametrize("text, field", [
    (BLOCK.replace("rect = { center = [0.4, 0.55], size = [0.5, 0.35] }", "circle = { center = [0.5, 0.5], radius = 0.2 }"),
     "layers[0].shapes[0]"),
    ('name = "one"\nperiod = 1.0\nsuperstrate = "air"\nsubstrate = "air"\n[[layers]]\nthickness = 0.1\nmaterial = "air"\n'
     'shapes = [ { material = 2.0, x = [0.2, 0.6] } ]\n', "period"),
])
def test_cells_it_cannot_stretch_are_refused_naming_the_field(text, field):
    with pytest.raises(UserInputError) as caught:
        solve_asr(Structure.from_toml_string(text), 550.0, 0.0, 0.0, 5)
    assert caught.value.field == field


def test_a_stretch_outside_zero_to_one_or_an_unknown_rule_is_refused():
    with pytest.raises(UserInputError) as caught:
        solve_asr(Structure.from_toml_string(BLOCK), 550.0, 0.0, 0.0, 5, eta=1.0)
    assert caught.value.field == "eta"
    with pytest.raises(UserInputError) as caught:
        solve_asr(Structure.from_toml_string(BLOCK), 550.0, 0.0, 0.0, 5, rule="laurent")
    assert caught.value.field == "factorization"


def test_the_2d_study_leaves_asr_out_for_a_cell_with_circles(tmp_path, monkeypatch):
    """rcwa.table_study.run_convergence_study: ASR stretches rectangles only, so a cell with a
    circle is studied with the other rules (the curve itself is rcwa.convergence's, not run here)."""
    import rcwa.table_study as table_study
    from rcwa.convergence import CurveConfig
    from rcwa.solve_cache import SolveCache

    seen = []

    def capture(structure, cache, cfg, bar):
        seen.append(cfg.rules)
        raise RuntimeError("captured")

    monkeypatch.setattr(table_study, "accuracy_versus_time", capture)
    for text, rules in ((BLOCK, ("li", "nv", "asr", "asr_nv")),
                        (BLOCK.replace("rect = { center = [0.4, 0.55], size = [0.5, 0.35] }",
                                       "circle = { center = [0.5, 0.5], radius = 0.2 }"), ("li", "nv"))):
        structure = Structure.from_toml_string(text)
        with pytest.raises(RuntimeError, match="captured"):
            cache = SolveCache(tmp_path / "c.json", structure)
            table_study.run_convergence_study(structure, tmp_path / "out", CurveConfig(), cache, progress=False)
        assert seen[-1] == rules
