"""Efficiency-table lookups inside Mitsuba kernels (Dr.Jit arrays and gathers).

The table (rcwa.table) is indexed by the incident light's (theta, phi) in the RCWA
convention: the tangential wave vector of the incident wave, i.e. pointing *away* from
the light (workbench.core.conventions). Interpolation is linear in wavelength and bilinear in
(theta, phi), the paper's choice ([Lange 2021, Sec. 2.2]); the accuracy study
(rcwa.table_study) measured it. Azimuths are folded into the stored range by the cell's mirror
symmetries, with the order flips (and, for a cell with the diagonal mirror x <-> y, the
swap (m, n) -> (n, m)) that go with them: the rule of rcwa.symmetry.fold_azimuths, which
rcwa.table.Table.fold_azimuth applies on the CPU (tests/renderer/test_efficiency_diagonal.py
compares this copy with it). Wavelengths outside the table give zero (the camera is checked to
be blind there before rendering).
"""

from __future__ import annotations

from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from rcwa.table import Table


def _uniform_axis(values: np.ndarray, name: str) -> tuple[float, float, int]:
    values = np.asarray(values, dtype=float)
    if values.size > 1:
        steps = np.diff(values)
        if not np.allclose(steps, steps[0], rtol=1e-6, atol=1e-9):
            raise ValueError(f"table axis {name} is not uniform")
        return float(values[0]), float(steps[0]), int(values.size)
    return float(values[0]), 1.0, 1


@dataclass
class EfficiencyLookup:
    """Kernel-side view of one table array (R, T, ...) for unpolarized light."""

    data: mi.Float
    wl: tuple[float, float, int]
    theta: tuple[float, float, int]
    phi: tuple[float, float, int]
    orders_m: np.ndarray
    orders_n: np.ndarray
    mirror_x: bool
    mirror_y: bool
    mirror_diagonal: bool = False  # x <-> y: stored azimuths 0-45 deg, orders swapped beyond

    def __post_init__(self) -> None:
        if self.mirror_diagonal and (self.orders_m.size != self.orders_n.size or
                                     np.unique(self.orders_m).size != np.unique(self.orders_n).size):
            raise ValueError("a table folded by the diagonal mirror needs square kept orders")

    @classmethod
    def from_table(cls, table: Table, array: str = "R") -> "EfficiencyLookup":
        names = table.meta["pol_names"]
        if "unpolarized" not in names:
            raise ValueError(f"{table.path}: the renderer needs unpolarized efficiencies (table has {names})")
        values = table.arrays[array][..., names.index("unpolarized")]  # (W, Th, Ph, K)
        mirror_x, mirror_y, mirror_diagonal = table.mirrors
        return cls(
            data=mi.Float(np.ascontiguousarray(values, dtype=np.float32).ravel()),
            wl=_uniform_axis(table.wavelengths_nm, "wavelength"),
            theta=_uniform_axis(table.theta_deg, "theta"),
            phi=_uniform_axis(table.phi_deg, "phi"),
            orders_m=np.asarray(table.meta["orders_m"]), orders_n=np.asarray(table.meta["orders_n"]),
            mirror_x=mirror_x, mirror_y=mirror_y, mirror_diagonal=mirror_diagonal,
        )

    @property
    def order_count(self) -> int:
        return int(self.orders_m.size)

    def order_index(self, m: int, n: int = 0) -> int:
        hits = np.flatnonzero((self.orders_m == m) & (self.orders_n == n))
        if hits.size == 0:
            raise KeyError(f"order ({m}, {n}) is not in the table")
        return int(hits[0])

    def fold(self, phi_deg: mi.Float) -> tuple[mi.Float, mi.Bool, mi.Bool, mi.Bool]:
        """Azimuth folded into the stored range, and whether m and n flip and then swap
        (rcwa.symmetry.fold_azimuths: y, then x, then the diagonal)."""
        phi = phi_deg - 360.0 * dr.floor(phi_deg / 360.0)
        flip_m = dr.zeros(mi.Bool, dr.width(phi))
        flip_n = dr.zeros(mi.Bool, dr.width(phi))
        swap = dr.zeros(mi.Bool, dr.width(phi))
        if self.mirror_y:
            upper = phi > 180.0
            phi = dr.select(upper, 360.0 - phi, phi)
            flip_n = upper
            if self.mirror_x:
                back = phi > 90.0
                phi = dr.select(back, 180.0 - phi, phi)
                flip_m = back
                if self.mirror_diagonal:
                    swap = phi > 45.0
                    phi = dr.select(swap, 90.0 - phi, phi)
        elif self.mirror_x:
            back = (phi > 90.0) & (phi < 270.0)
            phi = dr.select(back, 180.0 - phi, dr.select(phi >= 270.0, phi - 360.0, phi))
            flip_m = back
        return phi, flip_m, flip_n, swap

    def _flipped_index(self, k: mi.UInt32, flip_m: mi.Bool, flip_n: mi.Bool, swap: mi.Bool) -> mi.UInt32:
        """The stored index of kept order ``k`` after the fold: (m, n) -> (+-m, +-n) by the
        flips, then -> (n, m) by the swap (rcwa.symmetry.stored_order). Kept orders are
        m-major and symmetric about 0 in each direction, so -m is index count - 1 - i_m, and
        with square kept orders (the diagonal's condition) the swap exchanges i_m and i_n."""
        n_count = int(np.unique(self.orders_n).size)
        m_count = self.order_count // n_count
        i_m, i_n = k // n_count, k % n_count
        i_m = dr.select(flip_m, m_count - 1 - i_m, i_m)
        i_n = dr.select(flip_n, n_count - 1 - i_n, i_n)
        i_m, i_n = dr.select(swap, i_n, i_m), dr.select(swap, i_m, i_n)
        return mi.UInt32(i_m * n_count + i_n)

    def eval(self, k: mi.UInt32, wavelength_nm: mi.Float, theta_deg: mi.Float, phi_deg: mi.Float,
             active: mi.Bool | bool = True) -> mi.Float:
        """Efficiency of kept order ``k`` (index into orders_m/n) at the given incidence."""
        phi, flip_m, flip_n, swap = self.fold(phi_deg)
        k = self._flipped_index(k, flip_m, flip_n, swap)
        (w0, wf, w_in) = self._axis(wavelength_nm, self.wl, clamp=False)
        (t0, tf, _) = self._axis(theta_deg, self.theta)
        (p0, pf, _) = self._axis(phi, self.phi)
        n_w, n_t, n_p, n_k = self.wl[2], self.theta[2], self.phi[2], self.order_count
        result = dr.zeros(mi.Float, dr.width(theta_deg))
        for dw, ww in ((0, 1.0 - wf), (1, wf)):
            for dt, wt in ((0, 1.0 - tf), (1, tf)):
                for dp, wp in ((0, 1.0 - pf), (1, pf)):
                    wi = dr.minimum(w0 + dw, n_w - 1)
                    ti = dr.minimum(t0 + dt, n_t - 1)
                    pi = dr.minimum(p0 + dp, n_p - 1)
                    index = ((wi * n_t + ti) * n_p + pi) * n_k + k
                    result += ww * wt * wp * dr.gather(mi.Float, self.data, index, active & w_in)
        return dr.select(w_in & active, result, 0.0)

    @staticmethod
    def _axis(x: mi.Float, axis: tuple[float, float, int], clamp: bool = True):
        start, step, count = axis
        t = (x - start) / step
        inside = (t >= -1e-6) & (t <= count - 1 + 1e-6)
        t = dr.clip(t, 0.0, max(count - 1, 0))
        i0 = mi.UInt32(dr.minimum(dr.floor(t), max(count - 2, 0)))
        frac = dr.select(count > 1, t - mi.Float(i0), 0.0)
        return i0, frac, (inside if not clamp else mi.Bool(True))
