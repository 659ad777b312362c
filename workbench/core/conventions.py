"""Conventions shared by every module (see docs/architecture.md, "Conventions").

Written down once here and imported by the solver, the renderer and the tests.

* Time dependence ``exp(-i omega t)``: lossy media have ``Im(n) > 0``. Longitudinal wave
  numbers take the branch ``Im(kz) >= 0`` (``Re(kz) >= 0`` when ``Im(kz) == 0``), so
  waves decay or propagate away from the structure.
* Lengths inside rcwa in micrometres; wavelengths in nanometres at every interface
  between modules. Angles in degrees in files and on the command line, radians in code.
* Grating frame: ``z`` is the surface normal pointing into the superstrate (the incidence
  side, incident light travels toward ``-z``); ``x`` is the grating vector (across the
  grooves) of a 1D grating, ``y`` runs along the grooves. ``theta`` and ``phi`` of an
  RCWA solve are the polar angle from ``+z`` and the azimuth from ``+x`` toward ``+y`` of
  the *tangential incident wave vector*: ``k_inc = k0 n_sup (sin theta cos phi,
  sin theta sin phi, -cos theta)``. The specular order 0 leaves along ``(theta, phi)``;
  the light comes *from* the azimuth ``phi + pi`` (a renderer's light direction
  ``omega_i`` with azimuth ``phi_i`` is an RCWA solve at ``phi = phi_i + pi``).
* Orders: ``k_x,m = k_x,inc - m * 2 pi / Lambda_x`` (and ``k_y,n = k_y,inc - n * 2 pi /
  Lambda_y``), the sign of [Lange 2021, Eq. 2]: ``ORDER_SIGN`` below, which
  ``order_kx`` and the renderer's BWDF (Dr.Jit code, renderer/bwdf.py) both use.
* Polarization: ``s`` (TE, E perpendicular to the plane of incidence) and ``p`` (TM);
  ``unpolarized`` is the mean of the s and p efficiencies.
* Diffraction efficiency: the fraction of the incident power carried by an order through
  a plane ``z = const`` (lossless structures sum to 1 over R and T).
"""

from __future__ import annotations

import math
from enum import Enum
from typing import overload

import numpy as np


class Polarization(str, Enum):
    """Incident polarization. ``UNPOLARIZED`` is the mean of ``S`` and ``P``."""

    S = "s"
    P = "p"
    UNPOLARIZED = "unpolarized"


ORDER_SIGN = -1
"""The order sign: ``k_x,m = k_x,inc + ORDER_SIGN * m * 2 pi / Lambda_x`` [Lange 2021, Eq. 2]."""


def order_kx(kx_inc: float, m: np.ndarray | int, period: float, wavelength: float) -> np.ndarray:
    """Normalized tangential wave number of order ``m``: ``kx_inc + ORDER_SIGN * m * lambda / Lambda``.

    All quantities are divided by ``k0 = 2 pi / lambda`` ([Lange 2021, Eq. 2] sign).
    ``period`` and ``wavelength`` must share a unit.
    """
    return kx_inc + ORDER_SIGN * np.asarray(m, dtype=float) * (wavelength / period)


def order_kxy(
    kx_inc: float, ky_inc: float, m: np.ndarray | int, n: np.ndarray | int, period: tuple[float, ...], wavelength: float
) -> tuple[np.ndarray, np.ndarray]:
    """Normalized tangential wave vectors ``(kx, ky) / k0`` of orders ``(m, n)``, vectorized.

    Along each periodic axis the sign of ``order_kx`` (``ORDER_SIGN``):
    ``kx_inc + ORDER_SIGN * m * lambda / Lambda_x`` ([Lange 2021, Eq. 2]) and
    ``ky_inc + ORDER_SIGN * n * lambda / Lambda_y`` (its y-counterpart, [Lange 2021, Sec. 2.2]).
    ``period`` is ``(Lambda_x,)`` for a 1D grating, whose orders keep ``ky = ky_inc``
    (``n`` must be 0), or ``(Lambda_x, Lambda_y)``; it and ``wavelength`` share a unit.
    ``m`` and ``n`` broadcast against each other.
    """
    m_arr, n_arr = np.broadcast_arrays(np.asarray(m), np.asarray(n))
    kx = order_kx(kx_inc, m_arr, period[0], wavelength)
    if len(period) == 1:
        if np.any(n_arr != 0):
            raise ValueError("a 1D grating (one period) has only n = 0 orders")
        return kx, np.full(kx.shape, float(ky_inc))
    return kx, order_kx(ky_inc, n_arr, period[1], wavelength)


@overload
def incident_tangential_k(n_superstrate: float, theta_rad: float, phi_rad: float) -> tuple[float, float]: ...


@overload
def incident_tangential_k(n_superstrate: float, theta_rad: np.ndarray, phi_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ...


def incident_tangential_k(n_superstrate, theta_rad, phi_rad):
    """Normalized tangential wave vector ``(kx, ky) / k0`` of the incident wave.

    [Lange 2021, Eq. 2]: ``k_x = cos(phi) sin(theta) k0 n1`` and
    ``k_y = sin(phi) sin(theta) k0 n1``, so the incident wave's tangential wave vector
    points along the azimuth ``phi``; its direction of travel has ``k_z < 0``.
    The specularly reflected order 0 then leaves with the same ``(kx, ky)``.
    Scalars give floats (a single solve); arrays of directions broadcast (a sweep).
    """
    if np.ndim(theta_rad) == 0 and np.ndim(phi_rad) == 0:
        s = n_superstrate * math.sin(theta_rad)
        return s * math.cos(phi_rad), s * math.sin(phi_rad)
    s_arr = n_superstrate * np.sin(theta_rad)
    return s_arr * np.cos(phi_rad), s_arr * np.sin(phi_rad)


def kz_branch(kz_squared: np.ndarray) -> np.ndarray:
    """Square root with ``Im >= 0`` (``Re >= 0`` when ``Im == 0``): the outgoing branch.

    Used for the semi-infinite media, where the choice decides which wave is outgoing.
    A purely real argument (lossless medium) is treated as real, so that a round-off
    ``-0.0j`` cannot flip a propagating wave into a backward one.
    """
    z = np.asarray(kz_squared, dtype=complex)
    root = np.sqrt(z)
    flip = (root.imag < 0) | ((root.imag == 0) & (root.real < 0))
    return np.where(flip, -root, root)
