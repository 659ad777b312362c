"""Optical constants: a small cited library of built-in materials, constants and CSV files.

A :class:`Material` maps vacuum wavelengths in nanometres to the complex refractive index
``n + i k`` with ``k >= 0`` (the ``exp(-i omega t)`` convention of
:mod:`workbench.core.conventions`: lossy media have ``Im(n) > 0``) and to the relative
permittivity ``eps = (n + i k)**2``. Evaluation is vectorised: pass an array of wavelengths
and get an array back. Asking outside a material's data range raises
:class:`~workbench.core.errors.UserInputError`; nothing is extrapolated.

Built-in materials
------------------
Names are case-insensitive and blind to spaces, ``_`` and ``-`` (``"Fused Silica"``,
``"NBK7"``). Each data file ``rcwa/materials_data/<name>.toml`` holds the numbers as
published, with the full citation in its header.

===========================  ============================================  ==================  ============
name (aliases)               source                                        model               range (nm)
===========================  ============================================  ==================  ============
air                          vacuum value, as [Lange 2021, Sec. 3]         constant n = 1      all
polycarbonate (pc)           [Sultanova 2009]; Sellmeier fit (1)           Sellmeier, k = 0    360-1052 (*)
aluminum (aluminium, al)     [Rakic 1998], LD parameters (2)               Lorentz-Drude       206.6-12398
gold (au)                    [Johnson 1972, Table I] (3)                   tabulated, PCHIP    187.9-1937
silver (ag)                  [Johnson 1972, Table I] (3)                   tabulated, PCHIP    187.9-1937
silicon (si)                 [Green 2008, Table 1], 300 K                  tabulated, PCHIP    250-1450
fused_silica (silica, sio2)  [Malitson 1965], 20 degC                      Sellmeier, k = 0    210-3710
n-bk7 (bk7)                  SCHOTT N-BK7 data sheet, [SCHOTT TIE-29] (4)  Sellmeier, k = 0    300-2500
===========================  ============================================  ==================  ============

(*) measured 436.8-1052 nm; 360-436.8 nm extrapolates the Sellmeier fit (its single UV pole
at 146 nm lies far below polycarbonate's intrinsic absorption edge near 290 nm). Air's true
n - 1 ~ 2.8e-4 [Ciddor 1996] is neglected, as in the paper. The works are listed, by key, in
docs/references.md:

(1) a one-term Sellmeier fit to its indices [Polyanskiy 2024] (refractiveindex.info).
(2) the Lorentz-Drude model and its parameter table for Al (fit range 0.1-6 eV).
(3) n and k against photon energy 0.64-6.60 eV.
(4) the Zemax catalogue 2017-01-20b; Sellmeier form of [SCHOTT TIE-29]. k = 0: SCHOTT's
    transmittance data give k < 6e-8 over 360-830 nm.

User-given materials (``material_from_spec``)
---------------------------------------------
* a number: a real refractive index, ``> 0``, valid at every wavelength;
* ``{"n": 1.5, "k": 0.01}``: a constant complex index (``k`` optional, ``>= 0``);
* ``{"file": "ito.csv"}``: a CSV file (relative to ``base_dir``) with the header line
  ``wavelength_nm,n,k``, ``#`` comment lines allowed, at least two rows, wavelengths
  strictly increasing, ``n > 0`` and ``k >= 0``. Its range is its first to last wavelength.

Tabulated data (built-in or CSV) are interpolated in wavelength, ``n`` and ``k``
separately, by a monotone piecewise cubic (PCHIP, [Fritsch 1980]). PCHIP never overshoots
between two samples, so it keeps ``k >= 0`` and invents no spurious wiggles in sparse tables
such as Johnson & Christy's, while being smoother than linear interpolation.

Example
-------
>>> gold = material_from_spec("Au")
>>> complex(gold.refractive_index(HC_EV_NM / 1.88))   # Johnson & Christy's row at 1.88 eV
(0.14+3.697j)
>>> gold.epsilon(np.array([400.0, 500.0, 600.0])).shape
(3,)
"""

from __future__ import annotations

import functools
import numbers
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from scipy.interpolate import PchipInterpolator

from workbench.core import validation
from workbench.core.errors import UserInputError

__all__ = [
    "BUILTIN_MATERIALS",
    "HC_EV_NM",
    "ConstantIndex",
    "LorentzDrude",
    "Material",
    "Sellmeier",
    "Tabulated",
    "material_from_spec",
]

HC_EV_NM = 1239.841984
"""h c / e in eV nm ([CODATA 2018], exact SI constants): wavelength_nm = HC_EV_NM / energy_ev."""

BUILTIN_MATERIALS: tuple[str, ...] = (
    "air",
    "polycarbonate",
    "aluminum",
    "gold",
    "silver",
    "silicon",
    "fused_silica",
    "n-bk7",
)

_ALIASES: dict[str, str] = {
    "pc": "polycarbonate",
    "aluminium": "aluminum",
    "al": "aluminum",
    "au": "gold",
    "ag": "silver",
    "si": "silicon",
    "silica": "fused_silica",
    "sio2": "fused_silica",
    "bk7": "n-bk7",
}

CSV_HEADER = "wavelength_nm,n,k"
_CSV_EXPECTED = f"a CSV file with the header line '{CSV_HEADER}' and rows of three numbers"
_SPEC_EXPECTED = "a built-in name, a refractive index > 0, {n = ..., k = ...} or {file = 'data.csv'}"

Dispersion = Callable[[np.ndarray], np.ndarray]
"""Maps wavelengths in nm (a float array) to complex refractive indices of the same shape."""


# --------------------------------------------------------------------------- models
# One small frozen dataclass per published dispersion model; each is called with an
# array of vacuum wavelengths in nm and returns n + i k. Frozen and hashable, so two
# materials built from the same numbers compare equal.


@dataclass(frozen=True)
class ConstantIndex:
    """A wavelength-independent index ``n + i k``."""

    n: float
    k: float = 0.0

    def __call__(self, wavelength_nm: np.ndarray) -> np.ndarray:
        return np.full(np.shape(wavelength_nm), complex(self.n, self.k))


@dataclass(frozen=True)
class Sellmeier:
    """Sellmeier formula ``n^2 = 1 + sum_i B_i lambda^2 / (lambda^2 - C_i)``, ``k = 0``.

    ``lambda`` in micrometres and ``C_i`` in um^2: the form of [Malitson 1965] (there with
    ``C_i = lambda_i^2``) and of [SCHOTT TIE-29], section "Sellmeier dispersion equation".
    Valid only away from the poles ``lambda^2 = C_i``, i.e. inside the material's data range.
    """

    B: tuple[float, ...]
    C_um2: tuple[float, ...]

    def __call__(self, wavelength_nm: np.ndarray) -> np.ndarray:
        lam2 = (np.asarray(wavelength_nm, dtype=float) * 1e-3) ** 2
        n2 = 1.0 + sum(b * lam2 / (lam2 - c) for b, c in zip(self.B, self.C_um2, strict=True))
        return np.sqrt(n2).astype(complex)


@dataclass(frozen=True)
class LorentzDrude:
    """Lorentz-Drude permittivity of a metal [Rakic 1998].

    The paper's model is a free-electron (Drude) term plus ``k`` bound-electron (Lorentz)
    oscillators, with ``Omega_p = sqrt(f0) omega_p``::

        eps(w) = 1 - f0 wp^2 / (w (w + i G0)) + sum_j f_j wp^2 / (w_j^2 - w^2 - i w G_j)

    All frequencies as photon energies ``hbar w`` in eV. The signs of ``i`` are those of
    the ``exp(-i omega t)`` convention (``Im eps > 0``); a text written for
    ``exp(+i omega t)`` shows the complex conjugate. ``n + i k`` is the principal square
    root, which has ``n > 0`` and ``k >= 0`` because ``Im eps >= 0``.
    """

    plasma_ev: float
    f0: float
    gamma0_ev: float
    f: tuple[float, ...]
    omega_ev: tuple[float, ...]
    gamma_ev: tuple[float, ...]

    def epsilon(self, wavelength_nm: np.ndarray) -> np.ndarray:
        w = HC_EV_NM / np.asarray(wavelength_nm, dtype=float)
        wp2 = self.plasma_ev**2
        eps = 1.0 - self.f0 * wp2 / (w * (w + 1j * self.gamma0_ev))
        for fj, wj, gj in zip(self.f, self.omega_ev, self.gamma_ev, strict=True):
            eps = eps + fj * wp2 / (wj**2 - w**2 - 1j * w * gj)
        return eps

    def __call__(self, wavelength_nm: np.ndarray) -> np.ndarray:
        return np.sqrt(self.epsilon(wavelength_nm))


@dataclass(frozen=True)
class Tabulated:
    """``n`` and ``k`` sampled at increasing wavelengths (nm), each interpolated by PCHIP.

    PCHIP [Fritsch 1980] is monotone between
    neighbouring samples, so the interpolant stays within the sampled values and ``k``
    stays ``>= 0``. The final clip only removes round-off below zero.
    """

    wavelength_nm: tuple[float, ...]
    n: tuple[float, ...]
    k: tuple[float, ...]
    _interp: PchipInterpolator = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        nk = np.column_stack([self.n, self.k])
        object.__setattr__(self, "_interp", PchipInterpolator(self.wavelength_nm, nk, extrapolate=False))

    def __call__(self, wavelength_nm: np.ndarray) -> np.ndarray:
        nk = self._interp(wavelength_nm)
        return nk[..., 0] + 1j * np.maximum(nk[..., 1], 0.0)


# ------------------------------------------------------------------------- material


@dataclass(frozen=True)
class Material:
    """A named, cited dispersion with the wavelength range where it holds.

    ``wavelength_range_nm`` is ``(min, max)`` in nm, or ``None`` for a constant valid at
    every wavelength. Wavelengths are vacuum wavelengths in nm, scalars or arrays.
    """

    name: str
    citation: str
    wavelength_range_nm: tuple[float, float] | None
    dispersion: Dispersion = field(repr=False)

    def refractive_index(self, wavelength_nm: float | np.ndarray) -> np.ndarray:
        """Complex ``n + i k`` (``k >= 0``) at the given wavelengths, same shape."""
        return self.dispersion(self._checked(wavelength_nm))

    def epsilon(self, wavelength_nm: float | np.ndarray) -> np.ndarray:
        """Relative permittivity ``(n + i k)**2`` at the given wavelengths, same shape."""
        return self.refractive_index(wavelength_nm) ** 2

    def _checked(self, wavelength_nm: float | np.ndarray) -> np.ndarray:
        """The wavelengths as a float array; raises if any is non-positive or out of range."""
        try:
            wavelength = np.asarray(wavelength_nm, dtype=float)
        except (TypeError, ValueError):
            message = f"material '{self.name}': wavelength must be a number in nm"
            raise UserInputError(message, got=wavelength_nm) from None
        if wavelength.size == 0:
            return wavelength
        if wavelength.ndim == 0:  # one wavelength (every solve): no reductions
            shortest = longest = float(wavelength)
        else:
            shortest, longest = float(wavelength.min()), float(wavelength.max())
        if not (np.isfinite(shortest) and np.isfinite(longest)) or shortest <= 0.0:
            bad = shortest if not np.isfinite(shortest) or shortest <= 0.0 else longest
            raise UserInputError(f"material '{self.name}': wavelength must be finite and > 0 nm, asked for {bad:g} nm")
        if self.wavelength_range_nm is not None:
            low, high = self.wavelength_range_nm
            if shortest < low or longest > high:
                asked = shortest if shortest < low else longest
                raise UserInputError(
                    f"material '{self.name}' has data for {low:.6g}-{high:.6g} nm, asked for {asked:.6g} nm"
                )
        return wavelength


# ------------------------------------------------------------------------ from specs


def material_from_spec(spec: str | int | float | dict, *, base_dir: Path | None = None) -> Material:
    """Build a material from a structure-file value (see the module docstring).

    ``spec`` is a built-in name, a real refractive index, ``{"n": ..., "k": ...}`` or
    ``{"file": "data.csv"}`` (a relative path is taken relative to ``base_dir``, else to
    the working directory). Raises :class:`UserInputError` for anything malformed.
    """
    if isinstance(spec, str):
        return _builtin(_canonical_name(spec))
    if isinstance(spec, numbers.Real) and not isinstance(spec, bool):
        n = _index_value(spec, "n", minimum_exclusive=True, field=None)
        return Material(f"n={n:g}", "user-given constant refractive index", None, ConstantIndex(n))
    if isinstance(spec, Mapping):
        return _material_from_mapping(spec, base_dir)
    raise UserInputError("not a material", expected=_SPEC_EXPECTED, got=spec)


def _canonical_name(name: str) -> str:
    key = _name_key(name)
    if key in _LOOKUP:
        return _LOOKUP[key]
    raise UserInputError(
        f"unknown material '{name}'",
        expected=f"one of the built-in materials {', '.join(BUILTIN_MATERIALS)} "
        f"(aliases {', '.join(sorted(_ALIASES))}), a refractive index, {{n, k}} or {{file}}",
    )


def _name_key(name: str) -> str:
    """Lower case without spaces, '_' and '-': 'Fused Silica', 'fused_silica' -> 'fusedsilica'."""
    return "".join(ch for ch in name.strip().lower() if ch not in " _-")


_LOOKUP: dict[str, str] = {_name_key(n): n for n in BUILTIN_MATERIALS} | {
    _name_key(alias): name for alias, name in _ALIASES.items()
}


def _material_from_mapping(spec: Mapping[str, Any], base_dir: Path | None) -> Material:
    keys = set(spec)
    if "file" in keys:
        if keys != {"file"}:
            raise UserInputError("'file' cannot be combined with other keys", expected="{file = '...'}", got=dict(spec))
        return _material_from_csv(spec["file"], base_dir)
    if "n" in keys and keys <= {"n", "k"}:
        n = _index_value(spec["n"], "n", minimum_exclusive=True, field="n")
        k = _index_value(spec.get("k", 0.0), "k", minimum_exclusive=False, field="k")
        return Material(f"n={n:g}, k={k:g}", "user-given constant complex refractive index", None, ConstantIndex(n, k))
    raise UserInputError("a material table must be {n, k} or {file}", expected=_SPEC_EXPECTED, got=dict(spec))


def _index_value(value: Any, symbol: str, *, minimum_exclusive: bool, field: str | None) -> float:
    """A finite real ``n`` (> 0) or ``k`` (>= 0) from user input."""
    expected = f"a real number {'> 0' if minimum_exclusive else '>= 0'}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise UserInputError(f"{symbol} must be a number", field=field, expected=expected, got=value)
    number = float(value)
    if not np.isfinite(number) or number < 0.0 or (minimum_exclusive and number == 0.0):
        raise UserInputError(f"{symbol} out of range", field=field, expected=expected, got=value)
    return number


# ----------------------------------------------------------------------- CSV files


def _material_from_csv(file: Any, base_dir: Path | None) -> Material:
    if not isinstance(file, (str, Path)) or not str(file).strip():
        raise UserInputError("must be a path to a CSV file", field="file", expected=_CSV_EXPECTED, got=file)
    path = Path(file)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    wavelength, n, k = _read_csv(path)
    return Material(str(file), f"user data file {path}", (wavelength[0], wavelength[-1]), Tabulated(wavelength, n, k))


def _read_csv(path: Path) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """Rows ``(wavelength_nm, n, k)`` of a material CSV file, validated."""
    if not path.exists():
        raise UserInputError("material file not found", file=path, expected=_CSV_EXPECTED)
    data = validation.read_limited(path, "material")  # a device (/dev/zero) or a huge file is refused unread
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise UserInputError("material file is not UTF-8 text", file=path, expected=_CSV_EXPECTED) from None
    lines = [(i, s) for i, line in enumerate(text.splitlines(), 1) if (s := line.strip()) and not s.startswith("#")]
    if not lines:
        raise UserInputError("material file is empty", file=path, expected=_CSV_EXPECTED)
    header_line, header = lines[0]
    if [c.strip().lower() for c in header.split(",")] != CSV_HEADER.split(","):
        expected = f"the header line '{CSV_HEADER}'"
        raise UserInputError(f"line {header_line}: wrong header", file=path, expected=expected, got=header)
    rows = [_csv_row(line, number, path) for number, line in lines[1:]]
    return _validated_table(rows, [number for number, _ in lines[1:]], path)


def _csv_row(line: str, number: int, path: Path) -> tuple[float, float, float]:
    cells = line.split(",")
    try:
        if len(cells) != 3:
            raise ValueError
        wavelength, n, k = (float(c) for c in cells)
    except ValueError:
        expected = f"rows '{CSV_HEADER}' of numbers"
        raise UserInputError(f"line {number}: not three numbers", file=path, expected=expected, got=line) from None
    return wavelength, n, k


def _validated_table(
    rows: list[tuple[float, float, float]], line_numbers: list[int], path: Path
) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
    """Checks a table of ``(wavelength_nm, n, k)`` rows and returns its three columns."""
    if len(rows) < 2:
        message = f"material file has {len(rows)} data row(s)"
        raise UserInputError(message, file=path, expected="at least 2 rows for interpolation")
    checks = (
        (lambda w, n, k: all(map(np.isfinite, (w, n, k))), "values must be finite"),
        (lambda w, n, k: w > 0.0, "wavelength_nm must be > 0"),
        (lambda w, n, k: n > 0.0, "n must be > 0"),
        (lambda w, n, k: k >= 0.0, "k must be >= 0 (absorption; exp(-i omega t) convention)"),
    )
    for row, number in zip(rows, line_numbers, strict=True):
        for ok, rule in checks:
            if not ok(*row):
                raise UserInputError(f"line {number}: {rule}", file=path, got=row)
    for (previous, _, _), (current, _, _), number in zip(rows[:-1], rows[1:], line_numbers[1:], strict=True):
        if current <= previous:
            raise UserInputError(
                f"line {number}: wavelengths must increase strictly ({current:g} nm after {previous:g} nm)",
                file=path,
                expected="rows sorted by increasing wavelength_nm without repeats",
            )
    wavelength, n, k = zip(*rows, strict=True)
    return wavelength, n, k


# ------------------------------------------------------------------ built-in library


@functools.lru_cache(maxsize=None)
def _builtin(name: str) -> Material:
    """Load built-in material ``name`` (canonical) from ``materials_data/<name>.toml``, once."""
    source = resources.files("rcwa").joinpath("materials_data", f"{name}.toml")
    data = tomllib.loads(source.read_text(encoding="utf-8"))
    dispersion, wavelength_range = _MODEL_LOADERS[data["model"]](data, Path(str(source)))
    return Material(data["name"], data["citation"], wavelength_range, dispersion)


def _load_constant(data: dict[str, Any], _: Path) -> tuple[Dispersion, None]:
    return ConstantIndex(float(data["n"]), float(data.get("k", 0.0))), None


def _load_sellmeier(data: dict[str, Any], _: Path) -> tuple[Dispersion, tuple[float, float]]:
    c_um2 = data["C_um2"] if "C_um2" in data else [r * r for r in data["resonance_um"]]
    low, high = data["range_nm"]
    return Sellmeier(tuple(data["B"]), tuple(c_um2)), (float(low), float(high))


def _load_lorentz_drude(data: dict[str, Any], _: Path) -> tuple[Dispersion, tuple[float, float]]:
    low_ev, high_ev = data["range_ev"]
    model = LorentzDrude(
        data["plasma_ev"],
        data["f0"],
        data["gamma0_ev"],
        tuple(data["f"]),
        tuple(data["omega_ev"]),
        tuple(data["gamma_ev"]),
    )
    return model, (HC_EV_NM / high_ev, HC_EV_NM / low_ev)


def _load_tabulated(data: dict[str, Any], path: Path) -> tuple[Dispersion, tuple[float, float]]:
    """A table with columns ``[wavelength_nm | energy_ev, n, k]``, as the source printed it."""
    axis = data["columns"][0]
    rows = [(HC_EV_NM / x if axis == "energy_ev" else x, n, k) for x, n, k in data["table"]]
    rows.sort()
    wavelength, n, k = _validated_table(rows, list(range(1, len(rows) + 1)), path)
    return Tabulated(wavelength, n, k), (wavelength[0], wavelength[-1])


_MODEL_LOADERS: dict[str, Callable[[dict[str, Any], Path], tuple[Dispersion, tuple[float, float] | None]]] = {
    "constant": _load_constant,
    "sellmeier": _load_sellmeier,
    "lorentz_drude": _load_lorentz_drude,
    "tabulated": _load_tabulated,
}
