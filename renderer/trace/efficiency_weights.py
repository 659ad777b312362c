"""The prediction's efficiency weighting: each order's RCWA efficiency and the flat top's Fresnel transmission.

renderer.trace.prediction weighs each lit (pixel, wavelength) pair of order m (``weighting="efficiency"``,
the default) by eta_m T_in T_out, from here:

* eta_m(lambda, theta, phi): the order's diffraction efficiency for unpolarized light (the
  mean of s and p), computed by RCWA ([Moharam 1995a]) for the
  CD's structure: the scene's efficiency table (rcwa.table, the one renderer.tables serves
  for the scene: built into the cache when missing; scene_efficiency), read at the incident
  wave's direction inside the grating's superstrate (polycarbonate: sin theta = |k_inc| /
  n(lambda), phi its azimuth about the radial axis, folded by the cell's mirror
  symmetries with the order flip), linear in wavelength and bilinear in (theta, phi), as
  the table is meant to be read (Efficiency; renderer.efficiency does the same in its
  kernels); zero outside the table's wavelengths;
* T_in, T_out: the flat top's Fresnel transmission, unpolarized ((T_s + T_p) / 2; Born &
  Wolf, Principles of Optics, 7th ed., Sec. 1.5.2; fresnel_transmission), for the camera's
  ray and for the light's, each at its angle in air and the top's index (the n^2 law of
  radiance cancels between entering and leaving the top).

Why the efficiency (measured on cornell_cd, synthetic seed 0, 640 x 480, against renders
with the truth camera; benchmarks/bench_report.py ``--parts weighting``): along a radius the
lit wavelengths slide through the spectrum, about 5.5 nm per pixel, so a channel's band edge
along a radius is where its spectral weight runs out, and that weight is S_c E eta: the
first orders' efficiency falls from about 0.3 at 520-640 nm to 0.06-0.2 at 400 nm (the draft
table, theta 10-30 deg). With geometry alone the render's radius edges sit 1.51 px nearer
the centre than predicted (signed median; median |offset| 1.55 px; a 512 spp render, after
the BWDF's superstrate_index fix: renderer.trace.prediction, the non-dispersive top); weighted,
-0.37 px (median |offset| 0.50 px), near the renders' own noise: two independent 256 spp
renders differ by 0.52 px there. (Before that fix the render's orders carried a scaling
error, and the weighted offset was +0.04 px: the two errors happened to cancel. What leaves
-0.37 px is not known.) Along a circle a band ends where the light's rectangle ends (a
geometric edge, in every wavelength at once), so there the weighting changes little
(0.09-0.10 px either way).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcwa import symmetry
from rcwa.structure import Structure
from rcwa.table import open_table
from renderer.scene import SPECTRAL_RANGE_NM, SceneSpec
from renderer.spectra import camera_sensitivities
from renderer.tables import element_table, table_plan
from workbench.core.errors import UserInputError


@dataclass(frozen=True)
class Efficiency:
    """A 1D grating's unpolarized reflection efficiencies, read as a table is meant to be read.

    ``values`` (wavelength, theta, phi, order): rcwa.table's ``R`` for unpolarized light,
    theta the incident wave's polar angle in the superstrate and phi its azimuth about the
    grating vector, over the stored azimuths (``mirror_x``, ``mirror_y``: the cell's mirror
    symmetries, rcwa.symmetry). ``superstrate``: (wavelengths, n) of the superstrate's index
    on a 1 nm grid. ``source``: where the numbers come from (the table's path)."""

    wavelengths_nm: np.ndarray
    theta_deg: np.ndarray
    phi_deg: np.ndarray
    values: np.ndarray
    orders_m: tuple[int, ...]
    mirror_x: bool
    mirror_y: bool
    superstrate: tuple[np.ndarray, np.ndarray]
    source: str

    def fold(self, phi_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Azimuths mapped into the stored range and whether the order flips (m -> -m);
        rcwa.symmetry.fold_azimuths, the rule of rcwa.table.Table.fold_azimuth (a 1D grating's
        orders have n = 0, and a 1D cell never has the diagonal mirror)."""
        phi, flip, _, _ = symmetry.fold_azimuths(phi_deg, self.mirror_x, self.mirror_y)
        return phi, flip

    def __call__(self, m: int, wavelengths_nm: np.ndarray, sin_air: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
        """eta_m at each (wavelength, incident direction): ``sin_air`` = |k_inc| / k0, the
        incident wave's tangential wave vector (the same in air and, by Snell's law at the flat
        top, in the superstrate: sin theta = sin_air / n(lambda)); ``phi_deg`` its azimuth about
        the grating vector. Linear in wavelength, bilinear in (theta, phi); zero outside the
        table's wavelengths and for orders it does not keep."""
        lam = np.asarray(wavelengths_nm, float)
        n = np.interp(lam, *self.superstrate)
        theta = np.degrees(np.arcsin(np.clip(np.asarray(sin_air) / n, 0.0, 1.0)))
        phi, flip = self.fold(np.asarray(phi_deg, float))
        order = np.full(lam.shape, -1)
        for sign, where in ((m, ~flip), (-m, flip)):
            if sign in self.orders_m:
                order[where] = self.orders_m.index(sign)
        (w0, wf), (t0, tf), (p0, pf) = (_axis(self.wavelengths_nm, lam), _axis(self.theta_deg, theta),
                                         _axis(self.phi_deg, phi))
        out = np.zeros(lam.shape)
        k = np.maximum(order, 0)
        for dw, ww in ((0, 1.0 - wf), (1, wf)):
            for dt, wt in ((0, 1.0 - tf), (1, tf)):
                for dp, wp in ((0, 1.0 - pf), (1, pf)):
                    out += ww * wt * wp * self.values[w0 + dw, t0 + dt, p0 + dp, k]
        inside = (lam >= self.wavelengths_nm[0] - 1e-6) & (lam <= self.wavelengths_nm[-1] + 1e-6) & (order >= 0)
        return np.where(inside, out, 0.0)


def _axis(grid: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lower node index and fraction of ``x`` on a sorted grid, clamped to its ends (one-node
    grids give index 0, fraction 0; the upper index is then clamped by the caller's shape)."""
    if len(grid) < 2:
        return np.zeros(np.shape(x), int), np.zeros(np.shape(x))
    x = np.clip(x, grid[0], grid[-1])
    i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, len(grid) - 2)
    return i, (x - grid[i]) / (grid[i + 1] - grid[i])


def table_efficiency(path: str | Path) -> Efficiency:
    """The efficiencies of an rcwa.table (opened and verified: rcwa.table.open_table)."""
    table = open_table(path)
    names = table.meta["pol_names"]
    if "unpolarized" not in names or "R" not in table.arrays:
        raise UserInputError("the prediction needs the table's unpolarized reflection efficiencies", file=path,
                             expected="a table with pol 'unpolarized' (or 'both') and array R", got=names)
    structure = Structure.from_toml_string(table.meta["structure_text"], source=str(path))
    if structure.dimension != 1 or any(n != 0 for n in table.meta["orders_n"]):
        raise UserInputError("the prediction needs a 1D grating's table", file=path, got=f"period {structure.period}")
    values = np.asarray(table.arrays["R"][..., names.index("unpolarized")], float)
    if len(table.theta_deg) < 2 or len(table.phi_deg) < 2:  # one node: repeat it, so that node + 1 exists
        values = np.repeat(np.repeat(values, 2 if len(table.theta_deg) < 2 else 1, axis=1),
                           2 if len(table.phi_deg) < 2 else 1, axis=2)
    if len(table.wavelengths_nm) < 2:
        values = np.repeat(values, 2, axis=0)
    material = structure.superstrate
    lo, hi = material.wavelength_range_nm or SPECTRAL_RANGE_NM
    grid = np.arange(SPECTRAL_RANGE_NM[0], SPECTRAL_RANGE_NM[1] + 1e-9, 1.0)
    index = np.real(np.asarray(material.refractive_index(np.clip(grid, lo, hi)), complex))
    sym = table.meta["symmetry"]
    return Efficiency(table.wavelengths_nm, table.theta_deg, table.phi_deg, values,
                      tuple(int(m) for m in table.meta["orders_m"]), bool(sym["mirror_x"]), bool(sym["mirror_y"]),
                      (grid, index), str(path))


EFFICIENCY_CACHE_SIZE = 4
_efficiencies: dict[tuple[str, str], Efficiency] = {}


def scene_efficiency(spec: SceneSpec, index: int = 0, nodes=None) -> Efficiency:
    """The efficiencies of the scene's CD ``index``: the table renderer.tables serves for it
    (the scene's named table, or the cache's, built there when missing; planned with ``nodes``,
    an rcwa.table.NodePlan, where given: renderer.tables.table_plan). Read (and checksummed,
    about 1-2 s) once per process and request, however many cameras are predicted: the
    report's uncertainty band predicts several."""
    cd = spec.cds[index]
    where = f"cd[{index}]"
    plan = table_plan(cd, where, spec.source, nodes)
    key = (str(plan.path), plan.key)
    if key not in _efficiencies:
        path = element_table(cd, camera_sensitivities(spec.camera.sensitivities), where, spec.source, nodes=nodes,
                             progress=False)
        while len(_efficiencies) >= EFFICIENCY_CACHE_SIZE:
            _efficiencies.pop(next(iter(_efficiencies)))
        _efficiencies[key] = table_efficiency(path)
    return _efficiencies[key]


def fresnel_transmission(cos_i: np.ndarray, index: float | np.ndarray) -> np.ndarray:
    """Unpolarized Fresnel transmission (T_s + T_p) / 2 of light meeting a flat interface from
    air (index 1) at cos_i onto a medium of ``index`` (Born & Wolf, Principles of Optics, 7th ed.,
    Sec. 1.5.2: T = 1 - R, r_s = (cos_i - n cos_t) / (cos_i + n cos_t), r_p = (n cos_i - cos_t) /
    (n cos_i + cos_t)); the same for light leaving the medium into air at the refracted angle."""
    cos_i = np.clip(np.asarray(cos_i, float), 0.0, 1.0)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - cos_i**2) / np.asarray(index) ** 2, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (cos_i - index * cos_t) / (cos_i + index * cos_t)
        rp = (index * cos_i - cos_t) / (index * cos_i + cos_t)
    return np.where(cos_i > 0, 1.0 - 0.5 * (rs**2 + rp**2), 0.0)
