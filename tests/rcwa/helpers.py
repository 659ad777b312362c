"""Builders and independent references shared by the rcwa tests."""

from __future__ import annotations

import numpy as np

import rcwa


def nk(n: float, k: float = 0.0) -> dict:
    return {"n": n, "k": k}


def structure(period, superstrate, substrate, layers) -> "rcwa.Structure":
    return rcwa.Structure.from_dict(
        {"period": list(period), "superstrate": superstrate, "substrate": substrate, "layers": layers}, source="<test>"
    )


AIR = nk(1.0)
GLASS = nk(1.5)


def lamellar(period=1.0, depth=0.5, n_ridge=GLASS, n_groove=AIR, fill=(0.0, 0.5), sup=AIR, sub=GLASS):
    return structure(
        [period], sup, sub, [{"thickness": depth, "material": n_groove, "shapes": [{"material": n_ridge, "x": list(fill)}]}]
    )


def airy_rt(
    n_list: list[complex], d_list_um: list[float], wavelength_nm: float, theta_deg: float, pol: str
) -> tuple[float, float]:
    """R and T of a thin-film stack by the recursive Airy formula (Born & Wolf, 7th ed., Sec. 1.6.4).

    n_list: superstrate, layers..., substrate (complex indices, Im >= 0); d_list: layer
    thicknesses in micrometres. s waves use the admittance kz and E amplitudes, p waves
    kz / eps and H amplitudes; both give r_ij = (Y_i - Y_j)/(Y_i + Y_j), t_ij = 2 Y_i/(Y_i + Y_j).
    """
    k0 = 2 * np.pi / (wavelength_nm / 1000.0)
    s = n_list[0].real * np.sin(np.radians(theta_deg))
    kz = []
    for n in n_list:
        root = np.sqrt(complex(n) ** 2 - s**2)
        kz.append(-root if root.imag < 0 or (root.imag == 0 and root.real < 0) else root)
    Y = [k if pol == "s" else k / complex(n) ** 2 for k, n in zip(kz, n_list, strict=True)]
    r_ij = lambda i, j: (Y[i] - Y[j]) / (Y[i] + Y[j])  # noqa: E731
    t_ij = lambda i, j: 2 * Y[i] / (Y[i] + Y[j])  # noqa: E731
    last = len(n_list) - 1
    r, t = r_ij(last - 1, last), t_ij(last - 1, last)
    for j in range(last - 1, 0, -1):
        phase = np.exp(1j * kz[j] * k0 * d_list_um[j - 1])
        denom = 1 + r_ij(j - 1, j) * r * phase**2
        r, t = (r_ij(j - 1, j) + r * phase**2) / denom, t_ij(j - 1, j) * t * phase / denom
    R = abs(r) ** 2
    T = abs(t) ** 2 * Y[last].real / Y[0].real
    if complex(n_list[-1]).imag > 0:
        T = 0.0  # nothing reaches infinity in an absorbing substrate
    return R, T


def damage_chunk(chunk, damage: str) -> None:
    """Damage a stored table chunk file the way a disk or a careless hand would."""
    data = bytearray(chunk.read_bytes())
    if damage == "flip a byte":
        data[len(data) // 2] ^= 0xFF
        chunk.write_bytes(bytes(data))
    elif damage == "truncate":
        chunk.write_bytes(bytes(data[: len(data) // 3]))
    else:
        chunk.unlink()
