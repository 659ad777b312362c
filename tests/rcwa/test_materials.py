"""Tests of rcwa/materials.py: published values, physical constraints, user input errors."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from rcwa.materials import BUILTIN_MATERIALS, HC_EV_NM, Material, material_from_spec
from workbench.core.errors import UserInputError

# Tolerances, each with its reason.
TOL_CATALOGUE_5_DECIMALS = 2e-5
"""Glass catalogues print n to 5 decimals (half a unit: 5e-6); their Sellmeier fits
reproduce the printed values to about 1e-5."""
TOL_4_DECIMALS = 5e-5
"""A value quoted to 4 decimals: half a unit in the last place."""
TOL_SULTANOVA = 1.5e-3
"""Sultanova et al. state a refractometer accuracy of +-1e-3 and print 3 decimals (+-5e-4);
the one-term Sellmeier fit must stay within both."""
TOL_TABLE_ROW = 1e-12
"""At a tabulated wavelength the interpolant returns the sample itself, up to round-off."""
TOL_LD_RELATIVE = 1e-4
"""refractiveindex.info prints its tabulation of the Rakic LD model (and the wavelengths)
to 5 significant digits, so an exact implementation agrees to ~1e-5 relative."""

VISIBLE_NM = np.linspace(360.0, 830.0, 941)  # the renderer's range, 0.5 nm steps


def n_of(material: Material, wavelength_nm: float) -> complex:
    return complex(material.refractive_index(wavelength_nm))


# ------------------------------------------------------------------ published values


def test_n_bk7_catalogue_indices_and_abbe_number() -> None:
    """SCHOTT N-BK7 data sheet: n_d = 1.51680, n_F = 1.52238, n_C = 1.51432, v_d = 64.17."""
    bk7 = material_from_spec("N-BK7")
    n_d, n_f, n_c = (n_of(bk7, wl).real for wl in (587.5618, 486.1327, 656.2725))
    assert n_d == pytest.approx(1.51680, abs=TOL_CATALOGUE_5_DECIMALS)
    assert n_f == pytest.approx(1.52238, abs=TOL_CATALOGUE_5_DECIMALS)
    assert n_c == pytest.approx(1.51432, abs=TOL_CATALOGUE_5_DECIMALS)
    assert (n_d - 1.0) / (n_f - n_c) == pytest.approx(64.17, abs=0.01)  # printed to 2 decimals


def test_fused_silica_d_line_malitson() -> None:
    """Malitson 1965: n = 1.4585 at the helium d-line, 587.6 nm."""
    assert n_of(material_from_spec("fused silica"), 587.5618) == pytest.approx(1.4585, abs=TOL_4_DECIMALS)


@pytest.mark.parametrize(
    ("wavelength_nm", "n_measured"),
    [(436.8, 1.612), (486.1, 1.599), (587.6, 1.585), (632.8, 1.580), (703.0, 1.575), (833.0, 1.569), (879.0, 1.568),
     (1052.0, 1.565)],
)
def test_polycarbonate_reproduces_sultanova_2009(wavelength_nm: float, n_measured: float) -> None:
    """The Sellmeier fit against the indices printed by Sultanova, Kasarova, Nikolov 2009."""
    n = n_of(material_from_spec("pc"), wavelength_nm)
    assert n.real == pytest.approx(n_measured, abs=TOL_SULTANOVA)
    assert n.imag == 0.0


@pytest.mark.parametrize(
    ("name", "energy_ev", "n", "k"),
    [("gold", 1.88, 0.14, 3.697), ("gold", 2.50, 1.04, 1.833), ("silver", 2.01, 0.06, 4.152),
     ("silver", 3.50, 0.10, 1.419)],
)
def test_noble_metals_reproduce_johnson_christy_table(name: str, energy_ev: float, n: float, k: float) -> None:
    """Johnson & Christy 1972, Table I, rows at the given photon energies."""
    value = n_of(material_from_spec(name), HC_EV_NM / energy_ev)
    assert value.real == pytest.approx(n, abs=TOL_TABLE_ROW)
    assert value.imag == pytest.approx(k, abs=TOL_TABLE_ROW)


def test_silicon_reproduces_green_2008_row() -> None:
    """Green 2008, Table 1: n = 3.940, k = 0.019934 at 600 nm (300 K)."""
    value = n_of(material_from_spec("Si"), 600.0)
    assert value == pytest.approx(3.940 + 0.019934j, abs=TOL_TABLE_ROW)


@pytest.mark.parametrize(
    ("wavelength_um", "n", "k"),
    [(0.40143, 0.45683, 4.7236), (0.50230, 0.76990, 5.9264), (0.63376, 1.3441, 7.3089), (0.82662, 2.6882, 8.1165)],
)
def test_aluminium_lorentz_drude_matches_independent_tabulation(wavelength_um: float, n: float, k: float) -> None:
    """Rakic 1998 LD model for Al against refractiveindex.info's tabulation of the same model
    (an independent implementation and transcription of the parameters)."""
    value = n_of(material_from_spec("aluminium"), wavelength_um * 1000.0)
    assert value.real == pytest.approx(n, rel=TOL_LD_RELATIVE)
    assert value.imag == pytest.approx(k, rel=TOL_LD_RELATIVE)


def test_tabulated_interpolation_stays_between_neighbouring_rows() -> None:
    """PCHIP is monotone between samples: gold between its 1.88 and 2.01 eV rows."""
    low, high = HC_EV_NM / 2.01, HC_EV_NM / 1.88
    values = material_from_spec("gold").refractive_index(np.linspace(low, high, 50))
    assert np.all((values.real >= 0.14) & (values.real <= 0.21))
    assert np.all((values.imag >= 3.272) & (values.imag <= 3.697))


# ------------------------------------------------------------------ physics and shape


@pytest.mark.parametrize("name", BUILTIN_MATERIALS)
def test_builtins_cover_visible_with_k_nonnegative(name: str) -> None:
    material = material_from_spec(name)
    if material.wavelength_range_nm is not None:
        low, high = material.wavelength_range_nm
        assert low <= 360.0 and high >= 830.0
    index = material.refractive_index(VISIBLE_NM)
    assert index.shape == VISIBLE_NM.shape and index.dtype == np.complex128
    assert np.all(np.isfinite(index))
    assert np.all(index.imag >= 0.0), "exp(-i omega t): lossy media have Im(n) > 0"
    assert np.all(index.real > 0.0)
    np.testing.assert_allclose(material.epsilon(VISIBLE_NM), index**2, rtol=1e-15)


@pytest.mark.parametrize("name", ["aluminum", "gold", "silver"])
def test_metals_are_metallic_in_the_visible(name: str) -> None:
    """Re(eps) < 0 at 550-830 nm for Al, Au and Ag (free-electron response dominates)."""
    assert np.all(material_from_spec(name).epsilon(np.linspace(550.0, 830.0, 57)).real < 0.0)


@pytest.mark.parametrize("name", ["polycarbonate", "fused_silica", "n-bk7"])
def test_dielectrics_have_normal_dispersion(name: str) -> None:
    """Transparent glasses and polymers: n falls with wavelength across the visible."""
    assert np.all(np.diff(material_from_spec(name).refractive_index(VISIBLE_NM).real) < 0.0)


def test_evaluation_is_vectorised_and_keeps_shape() -> None:
    gold = material_from_spec("gold")
    grid = np.linspace(400.0, 700.0, 12).reshape(3, 4)
    values = gold.refractive_index(grid)
    assert values.shape == (3, 4)
    assert np.array_equal(values.ravel(), [n_of(gold, w) for w in grid.ravel()])
    assert gold.refractive_index(550.0).shape == ()


@pytest.mark.parametrize(
    ("spec", "canonical"),
    [("PC", "polycarbonate"), ("Aluminium", "aluminum"), ("al", "aluminum"), ("AU", "gold"), ("ag", "silver"),
     ("si", "silicon"), ("fused silica", "fused_silica"), ("Fused_Silica", "fused_silica"), ("silica", "fused_silica"),
     ("SiO2", "fused_silica"), ("bk7", "n-bk7"), ("NBK7", "n-bk7"), (" N-BK7 ", "n-bk7"), ("Air", "air")],
)
def test_names_are_case_insensitive_with_aliases(spec: str, canonical: str) -> None:
    material = material_from_spec(spec)
    assert material.name == canonical
    assert material is material_from_spec(canonical), "built-ins are loaded once and cached"


@pytest.mark.parametrize("name", BUILTIN_MATERIALS)
def test_builtin_data_files_are_cited(name: str) -> None:
    path = Path(__file__).parents[2] / "rcwa" / "materials_data" / f"{name}.toml"
    text = path.read_text(encoding="utf-8")
    assert text.startswith("#") and "# Source" in text
    data = tomllib.loads(text)
    assert data["name"] == name
    assert material_from_spec(name).citation == data["citation"] != ""


def test_constants_from_number_and_table() -> None:
    glass = material_from_spec(1.5)
    assert glass.wavelength_range_nm is None
    assert n_of(glass, 10.0) == 1.5 and n_of(glass, 1e6) == 1.5
    absorber = material_from_spec({"n": 2, "k": 0.25})
    assert n_of(absorber, 550.0) == 2.0 + 0.25j
    assert complex(absorber.epsilon(550.0)) == pytest.approx((2.0 + 0.25j) ** 2)
    assert material_from_spec({"n": 1.5}) == material_from_spec({"n": 1.5, "k": 0.0})
    assert material_from_spec(1.5) == material_from_spec(1.5) and len({material_from_spec(1.5), glass}) == 1


def test_import_does_not_need_the_compiled_core() -> None:
    code = "import sys, rcwa.materials; sys.exit('rcwa._core' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], cwd=Path(__file__).parents[2]).returncode == 0


# ----------------------------------------------------------------------------- errors


def test_out_of_range_names_material_wavelength_and_range() -> None:
    with pytest.raises(UserInputError, match=r"material 'gold' has data for 187\.855-1937\.25 nm, asked for 2000 nm"):
        material_from_spec("gold").refractive_index(np.array([500.0, 2000.0]))
    with pytest.raises(UserInputError, match=r"'polycarbonate' has data for 360-1052 nm, asked for 350 nm"):
        material_from_spec("pc").epsilon(350.0)


@pytest.mark.parametrize("wavelength", [0.0, -500.0, float("nan"), float("inf"), "green"])
def test_nonphysical_wavelength_is_rejected(wavelength: object) -> None:
    with pytest.raises(UserInputError, match="wavelength"):
        material_from_spec(1.5).refractive_index(wavelength)  # type: ignore[arg-type]


def test_unknown_name_lists_the_builtins() -> None:
    with pytest.raises(UserInputError) as info:
        material_from_spec("unobtainium")
    message = str(info.value)
    assert "unknown material 'unobtainium'" in message
    assert all(name in message for name in BUILTIN_MATERIALS)


@pytest.mark.parametrize(
    ("spec", "field"),
    [(0, None), (-1.5, None), (float("nan"), None), (float("inf"), None), (True, None), (None, None), ([1.5], None),
     ({"n": 0}, "n"), ({"n": -1.0}, "n"), ({"n": "1.5"}, "n"), ({"n": True}, "n"), ({"n": 1.5, "k": -0.01}, "k"),
     ({"n": 1.5, "k": float("nan")}, "k"), ({"k": 0.1}, None), ({"n": 1.5, "colour": "red"}, None), ({}, None),
     ({"file": "a.csv", "n": 1.5}, None), ({"file": 3}, "file"), ({"file": ""}, "file")],
)
def test_malformed_specs_are_user_errors(spec: object, field: str | None) -> None:
    with pytest.raises(UserInputError) as info:
        material_from_spec(spec)  # type: ignore[arg-type]
    assert info.value.field == field
    assert info.value.expected


GOOD_CSV = "# ITO film, ellipsometry\nwavelength_nm,n,k\n400,2.0,0.02\n# mid\n550, 1.9, 0.01\n\n700,1.8,0.005\n"


@pytest.mark.parametrize(
    ("content", "message"),
    [("", "empty"), ("# only a comment\n", "empty"), ("lambda,n,k\n400,1.5,0\n500,1.5,0\n", "header"),
     ("wavelength_nm,n\n400,1.5\n500,1.5\n", "header"), ("wavelength_nm,n,k\n400,1.5\n500,1.5,0\n", "line 2"),
     ("wavelength_nm,n,k\n400,1.5,0,1\n500,1.5,0\n", "line 2"), ("wavelength_nm,n,k\n400,1.5,0\n500,abc,0\n", "line 3"),
     ("wavelength_nm,n,k\n500,1.5,0\n400,1.5,0\n", "increase"),
     ("wavelength_nm,n,k\n400,1.5,0\n400,1.6,0\n", "increase"),
     ("wavelength_nm,n,k\n400,1.5,0\n500,1.5,-0.1\n", "k must be >= 0"),
     ("wavelength_nm,n,k\n400,0,0\n500,1.5,0\n", "n must"),
     ("wavelength_nm,n,k\n400,1.5,nan\n500,1.5,0\n", "finite"), ("wavelength_nm,n,k\n-400,1.5,0\n500,1.5,0\n", "> 0"),
     ("wavelength_nm,n,k\n400,1.5,0\n", "at least 2 rows")],
)
def test_malformed_csv_files_name_the_file(tmp_path: Path, content: str, message: str) -> None:
    (tmp_path / "bad.csv").write_text(content)
    with pytest.raises(UserInputError, match=message) as info:
        material_from_spec({"file": "bad.csv"}, base_dir=tmp_path)
    assert info.value.file == str(tmp_path / "bad.csv")
    assert str(tmp_path / "bad.csv") in str(info.value)


def test_missing_csv_file(tmp_path: Path) -> None:
    with pytest.raises(UserInputError, match="not found") as info:
        material_from_spec({"file": "absent.csv"}, base_dir=tmp_path)
    assert info.value.file == str(tmp_path / "absent.csv")
    assert "wavelength_nm,n,k" in str(info.value)


def test_csv_round_trip(tmp_path: Path) -> None:
    (tmp_path / "ito.csv").write_text(GOOD_CSV)
    ito = material_from_spec({"file": "ito.csv"}, base_dir=tmp_path)
    assert ito.name == "ito.csv" and ito.wavelength_range_nm == (400.0, 700.0)
    np.testing.assert_allclose(ito.refractive_index([400.0, 550.0, 700.0]), [2.0 + 0.02j, 1.9 + 0.01j, 1.8 + 0.005j])
    with pytest.raises(UserInputError, match="'ito.csv' has data for 400-700 nm, asked for 701 nm"):
        ito.refractive_index(701.0)

    silicon = material_from_spec("silicon")  # write a built-in out and read it back
    grid = np.arange(360.0, 831.0, 10.0)
    values = silicon.refractive_index(grid)
    rows = "".join(f"{float(w)!r},{v.real!r},{v.imag!r}\n" for w, v in zip(grid, values.tolist(), strict=True))
    (tmp_path / "si.csv").write_text("# Green 2008 resampled\nwavelength_nm,n,k\n" + rows)
    copy = material_from_spec({"file": str(tmp_path / "si.csv")})  # absolute path, no base_dir
    assert np.array_equal(copy.refractive_index(grid), values)
