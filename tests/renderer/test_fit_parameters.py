"""The scene file's ``[fit]`` table (renderer.fit_parameters), the fit values applied to a
scene (reports.scene_fit.apply) and the fitted scene file (reports.scene_fit.outputs): fast,
no rendering, no photos.

Each test says what it guards. Tolerances: values that pass through float arithmetic only
(a parsed number, a bound computed as nominal +- a half-width) are compared to 1e-12; a
tilt's angle goes through tan, a normalisation and arccos, good to ~1e-14 rad, checked to
1e-9 degrees; a TOML round trip writes floats exactly (shortest repr), so it is compared
exactly up to 1e-12.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rcwa.structure import load_structure
from renderer.fit_parameters import DEFAULT_FREE, HELD, FitTable, parse_fit_table
from renderer.scene import load_scene
from reports.scene_fit.apply import apply_values, tilt_angle_deg, tilted_normal
from reports.scene_fit.outputs import fitted_scene_data, write_fitted_scene
from workbench.cli import main
from workbench.core.errors import UserInputError

ROOT = Path(__file__).resolve().parents[2]
SCENE_TEXT = (ROOT / "renderer" / "scenes" / "cornell_cd.toml").read_text()
EXACT = 1e-12
TILT_TOL_DEG = 1e-9


def _scene_file(tmp_path: Path, fit: str, *, text: str = SCENE_TEXT, name: str = "fit_scene.toml") -> Path:
    """cornell_cd.toml with ``fit`` (the body of a [fit] table) appended, under tmp_path."""
    path = tmp_path / name
    path.write_text(text + "\n[fit]\n" + fit + "\n")
    return path


def _fit(spec) -> FitTable:
    """The scene's parsed [fit] table (parse_scene always sets it)."""
    assert spec.fit is not None
    return spec.fit


def _refused(path: Path, field: str) -> str:
    """The UserInputError's message for loading ``path``; it must name the file and ``field``."""
    with pytest.raises(UserInputError) as info:
        load_scene(path)
    message = str(info.value)
    assert str(path) in message, message
    assert f"field '{field}'" in message, message
    return message


# ---------------------------------------------------------------- the defaults


def test_builtin_scene_gets_the_defaults_with_bounds_about_the_file_values():
    """cornell_cd has no [fit]: the fit must vary the CD's pitch, its tilt and the light's
    x, z (DEFAULT_FREE, in that order) starting from the file's values, and the bounds
    must contain them, or the fit would start outside its own box."""
    spec = load_scene("cornell_cd")
    table = _fit(spec)
    assert table is not None and not table.declared and table.held == {}
    assert tuple(p.name for p in table.free) == DEFAULT_FREE
    period, normal, light = table.free
    assert (period.kind, period.cd_index, period.unit) == ("period", 0, "um")
    assert period.nominal == pytest.approx((1.6,), abs=EXACT)  # rcwa/structures/cd.toml: the Red Book pitch
    assert (normal.kind, normal.components, normal.unit) == ("normal", ("tilt_e1", "tilt_e2"), "deg")
    assert normal.nominal == (0.0, 0.0)  # tilts are measured from the file's normal
    assert (light.kind, light.components, light.unit) == ("light.center", ("x", "z"), "m")
    assert light.nominal == pytest.approx((spec.light.center[0], spec.light.center[2]), abs=EXACT)
    lower, upper = table.bounds()
    nominal = table.nominal()
    assert table.size == 5 and nominal.shape == lower.shape == upper.shape == (5,)
    assert np.all(lower < nominal) and np.all(nominal < upper)
    assert table.labels() == ["cd[0].structure.period:value", "cd[0].normal:tilt_e1", "cd[0].normal:tilt_e2",
                              "light.center:x", "light.center:z"]


def test_scene_without_a_cd_has_nothing_to_fit():
    """No CD: the defaults name cd[0], which does not exist; the table must be empty
    rather than an error, so that such scenes still load for every other command."""
    table = parse_fit_table(None, (), load_scene("cornell_cd").light)
    assert table.free == () and table.size == 0 and not table.declared


# ---------------------------------------------------------------- a declared [fit]


def test_declared_table_parses_bounds_within_within_deg_and_prior_std(tmp_path):
    """Each option does what docs/scene_format.md says: bounds are taken as written,
    ``within`` is +- about the file's value in the field's unit (metres here),
    ``within_deg`` the same for a normal's tilts, ``prior_std`` one number per component."""
    path = _scene_file(tmp_path, '"cd[0].structure.period" = { bounds = [1.5, 1.7] }\n'
                                 '"cd[0].normal" = { within_deg = 5.0 }\n'
                                 '"light.center" = { within = 0.10, prior_std = 0.05 }\n'
                                 '"cd[0].center" = { bounds = [[0.27, 0.29], [0.02, 0.03], [0.24, 0.26]] }\n'
                                 '"cd[0].structure.layers[0].thickness" = { prior_std = 0.01 }\n')
    spec = load_scene(path)
    table = _fit(spec)
    assert table.declared and table.held == {}
    period, normal, light, center, thickness = table.free
    assert period.lower == pytest.approx((1.5,), abs=EXACT) and period.upper == pytest.approx((1.7,), abs=EXACT)
    assert period.prior_std is None
    assert normal.lower == pytest.approx((-5.0, -5.0), abs=EXACT) and normal.upper == pytest.approx((5.0, 5.0), abs=EXACT)
    cx, cz = spec.light.center[0], spec.light.center[2]
    assert light.lower == pytest.approx((cx - 0.10, cz - 0.10), abs=EXACT)
    assert light.upper == pytest.approx((cx + 0.10, cz + 0.10), abs=EXACT)
    assert light.prior_std == (0.05, 0.05)  # one number: the same for x and z
    assert center.components == ("x", "y", "z") and center.nominal == pytest.approx(spec.cds[0].center, abs=EXACT)
    assert center.lower == pytest.approx((0.27, 0.02, 0.24), abs=EXACT)
    assert center.upper == pytest.approx((0.29, 0.03, 0.26), abs=EXACT)
    assert (thickness.kind, thickness.layer, thickness.nominal) == ("thickness", 0, pytest.approx((0.11,), abs=EXACT))
    assert thickness.prior_std == (0.01,)
    assert table.size == 1 + 2 + 2 + 3 + 1


def test_an_empty_option_table_takes_the_defaults(tmp_path):
    """``{}`` is documented as 'the defaults': the same bounds as the built-in defaults."""
    path = _scene_file(tmp_path, '"cd[0].structure.period" = {}\n"cd[0].normal" = {}\n"light.center" = {}\n')
    declared, default = _fit(load_scene(path)), _fit(load_scene("cornell_cd"))
    assert declared.declared and not default.declared
    assert declared.free == default.free


def test_light_power_is_accepted_and_held_not_free(tmp_path):
    """light.power_w cannot be told from the exposure in one photo (calibration fits their
    product): it must be accepted, listed in ``held`` with that reason, and not fitted."""
    path = _scene_file(tmp_path, '"light.power_w" = {}\n"light.center" = {}\n')
    table = _fit(load_scene(path))
    assert table.held == {"light.power_w": HELD["light.power_w"]}
    assert [p.name for p in table.free] == ["light.center"]


BAD = {
    # a CD index the scene does not have (cornell_cd has one CD)
    "no cd[3]": ('"cd[3].center" = {}', "fit.cd[3].center", "no cd[3]"),
    # a light field that is not a fit parameter
    "light.colour": ('"light.colour" = {}', "fit.light.colour", "names no field"),
    # a layer the CD's structure does not have (cd.toml has one layer)
    "no layers[5]": ('"cd[0].structure.layers[5].thickness" = {}', "fit.cd[0].structure.layers[5].thickness",
                     "no layers[5]"),
    # bounds that exclude the file's value (the period is 1.6 um)
    "bounds exclude nominal": ('"cd[0].structure.period" = { bounds = [1.7, 1.8] }', "fit.cd[0].structure.period.bounds",
                               "must contain the scene file's value"),
    # the rotation of circular tracks about their centre changes nothing the photos show
    "rotation": ('"cd[0].rotation_deg" = {}', "fit.cd[0].rotation_deg", "not identifiable"),
    # an option key that is not one of bounds, within, within_deg, prior_std
    "unknown option": ('"light.center" = { widthin = 0.1 }', "fit.light.center", "unknown option 'widthin'"),
    # within_deg is a normal's option: on a centre in metres it must not be dropped silently
    "within_deg on a centre": ('"light.center" = { within_deg = 5.0 }', "fit.light.center.within_deg", "within"),
    # within is in the field's unit; a normal's tilt takes within_deg, not a silently ignored within
    "within on a normal": ('"cd[0].normal" = { within = 5.0 }', "fit.cd[0].normal.within", "within_deg"),
    # bounds and within both given: one of them would be ignored
    "bounds and within": ('"cd[0].structure.period" = { bounds = [1.5, 1.7], within = 0.05 }',
                          "fit.cd[0].structure.period", "not both"),
    # a wrong number of per-component bounds (light.center has x and z)
    "bounds size": ('"light.center" = { bounds = [0.1, 0.4] }', "fit.light.center.bounds", "for each of 2 components"),
    "prior not positive": ('"light.center" = { prior_std = [0.05, 0.0] }', "fit.light.center.prior_std",
                           "must be positive"),
    # an option value that is not a table
    "not a table": ('"light.center" = 0.1', "fit.light.center", "must be a table of options"),
    # a shape the CD's layer does not have (cd.toml's pits layer holds one stripe)
    "no shapes[2]": ('"cd[0].structure.layers[0].shapes[2].width" = {}', "fit.cd[0].structure.layers[0].shapes[2].width",
                     "no stripe shapes[2]"),
    # a stripe cannot be wider than the 1.6 um period
    "width over the period": ('"cd[0].structure.layers[0].shapes[0].width" = { bounds = [0.4, 1.8] }',
                              "fit.cd[0].structure.layers[0].shapes[0].width.bounds", "wider than the period"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_fit_entries_are_refused_naming_file_and_field(tmp_path, case):
    """A mistake in [fit] is a UserInputError that names the scene file and ``fit.<name>``
    (the CLI prints it as one line, exit 2), never a silently different fit."""
    entry, field, words = BAD[case]
    message = _refused(_scene_file(tmp_path, entry), field)
    assert words in message, message


def test_a_cd_with_a_2d_structure_has_no_period_to_fit(tmp_path):
    """A CD's tracks are a 1D grating; gold2d's two periods cannot be one fit parameter."""
    text = SCENE_TEXT.replace('structure = "cd"', 'structure = "gold2d"')
    assert text != SCENE_TEXT
    path = _scene_file(tmp_path, '"cd[0].structure.period" = {}', text=text)
    assert "has no single period" in _refused(path, "fit.cd[0].structure.period")


def test_the_defaults_leave_out_a_period_a_2d_cd_lacks(tmp_path):
    """A scene without [fit] whose CD is 2D still loads: its default fit has no period (every
    command loads scenes, and the user never wrote the field)."""
    path = tmp_path / "scene.toml"
    path.write_text(SCENE_TEXT.replace('structure = "cd"', 'structure = "gold2d"'))
    spec = load_scene(path)
    assert spec.fit is not None and "cd[0].structure.period" not in {p.name for p in spec.fit.free}
    assert {p.name for p in spec.fit.free} == {"cd[0].normal", "light.center"}


def test_fit_must_be_a_table(tmp_path):
    """``fit = 3`` (not a table) names the field ``fit``."""
    path = tmp_path / "scene.toml"
    path.write_text(SCENE_TEXT.replace('name = "cornell_cd"', 'name = "cornell_cd"\nfit = 3'))
    assert "must be a table" in _refused(path, "fit")


# ---------------------------------------------------------------- values applied


@pytest.mark.parametrize("tilt", [-7.5, 0.0, 3.0, 20.0])
def test_a_tilt_toward_e1_turns_the_normal_by_that_angle(tilt):
    """A tilt of (a, 0) degrees must turn the normal by |a| (the fit's tilts are angles,
    whose std the report gives in degrees); checked at the CD's tilted file normal and at
    a rotated frame, through apply_values and tilted_normal alike."""
    spec = load_scene("cornell_cd")
    table = FitTable(tuple(p for p in _fit(spec).free if p.kind == "normal"), {}, True)
    original = np.asarray(spec.cds[0].normal)
    applied = apply_values(spec, table, np.array([tilt, 0.0]))
    turned = np.asarray(applied.spec.cds[0].normal)
    assert np.linalg.norm(turned) == pytest.approx(1.0, abs=EXACT)
    assert tilt_angle_deg(original, turned) == pytest.approx(abs(tilt), abs=TILT_TOL_DEG)
    for rotation in (0.0, 33.0):
        n = tilted_normal(original, rotation, np.array([0.0, tilt]))
        assert tilt_angle_deg(original, n) == pytest.approx(abs(tilt), abs=TILT_TOL_DEG)
    assert applied.structure_changes == {}
    assert applied.spec.cds[0].center == spec.cds[0].center  # only the normal was free


def test_light_centre_changes_x_and_z_and_keeps_the_ceiling_height():
    """light.center's components are x and z: the light stays in the ceiling (y kept)."""
    spec = load_scene("cornell_cd")
    table = FitTable(tuple(p for p in _fit(spec).free if p.kind == "light.center"), {}, True)
    applied = apply_values(spec, table, np.array([0.30, 0.25]))
    assert applied.spec.light.center == (0.30, spec.light.center[1], 0.25)
    assert applied.spec.light.size == spec.light.size and applied.spec.light.power_w == spec.light.power_w


def test_period_goes_into_structure_changes_not_the_spec():
    """The period is a field of the structure file: apply_values returns it beside the
    spec (the forward model reads it there), and the CD's placement is untouched."""
    spec = load_scene("cornell_cd")
    values = _fit(spec).nominal().copy()
    values[0] = 1.65
    applied = apply_values(spec, _fit(spec), values)
    assert applied.structure_changes == {0: {"period": 1.65}}
    assert applied.period_um(0) == 1.65 and applied.period_um(1) is None
    assert applied.spec.cds[0].structure == spec.cds[0].structure
    assert np.allclose(applied.spec.cds[0].normal, spec.cds[0].normal, atol=EXACT)  # tilts 0, 0: the same normal


# ---------------------------------------------------------------- the fitted scene file


def test_fitted_scene_round_trips_through_load_scene(tmp_path):
    """fitted_scene.toml is 'a scene any command accepts': written with a changed period
    and light centre, loaded back, it must hold those values, its structure copy must load
    (with the period in it) and the [fit] it carries must still parse."""
    source = _scene_file(tmp_path, '"cd[0].structure.period" = { bounds = [1.5, 1.7] }\n"light.center" = {}\n')
    spec = load_scene(source)
    values = np.array([1.62, 0.30, 0.26])
    out = tmp_path / "out"
    out.mkdir()
    data = fitted_scene_data(spec, _fit(spec), values, out)
    assert data["light"]["center"] == [0.30, spec.light.center[1], 0.26]
    path = write_fitted_scene(spec, _fit(spec), values, out, "a test\nof two lines")
    assert path == out / "fitted_scene.toml" and path.read_text().startswith("# a test\n# of two lines\n")
    fitted = load_scene(path)
    assert fitted.light.center == pytest.approx((0.30, spec.light.center[1], 0.26), abs=EXACT)
    assert Path(fitted.cds[0].structure).resolve() == (out / "cd0_structure.toml").resolve()
    structure = load_structure(fitted.cds[0].structure)
    assert structure.period == pytest.approx((1.62,), abs=EXACT)
    original = load_structure(spec.cds[0].structure)
    assert [layer.thickness for layer in structure.layers] == [layer.thickness for layer in original.layers]
    assert fitted.cds[0].center == pytest.approx(spec.cds[0].center, abs=EXACT)
    assert fitted.cds[0].normal == pytest.approx(spec.cds[0].normal, abs=EXACT)
    assert [p.name for p in _fit(fitted).free] == ["cd[0].structure.period", "light.center"]
    assert _fit(fitted).free[0].nominal == pytest.approx((1.62,), abs=EXACT)  # the fitted value is the new nominal


def test_fitted_structure_copy_keeps_a_relative_material_file(tmp_path):
    """A structure file whose material is a CSV next to it (``{ file = "film.csv" }``,
    relative to the structure file): the copy is written in another folder, so the
    reference must still find the CSV, or the fitted scene would not load."""
    scene_dir = tmp_path / "scene"
    scene_dir.mkdir()
    (scene_dir / "film.csv").write_text("wavelength_nm,n,k\n300,1.5,0.0\n900,1.5,0.0\n")
    (scene_dir / "my_cd.toml").write_text('period = [1.6]\nsuperstrate = { file = "film.csv" }\nsubstrate = "aluminum"\n\n'
                                          '[[layers]]\nthickness = 0.11\nmaterial = { file = "film.csv" }\n'
                                          'shapes = [ { material = "aluminum", x = [0.5, 1.1] } ]\n')
    text = SCENE_TEXT.replace('structure = "cd"', 'structure = "my_cd.toml"')
    spec = load_scene(_scene_file(scene_dir, '"cd[0].structure.layers[0].thickness" = {}', text=text))
    out = tmp_path / "out"
    out.mkdir()
    fitted = load_scene(write_fitted_scene(spec, _fit(spec), np.array([0.12]), out, "thickness"))
    structure = load_structure(fitted.cds[0].structure)
    assert structure.layers[0].thickness == pytest.approx(0.12, abs=EXACT)
    assert structure.period == (1.6,)


# ---------------------------------------------------------------- the command line


def test_cli_fit_with_a_bad_fit_field_exits_2_with_one_line(tmp_path, capsys):
    """`workbench fit` loads the scene before it reads the dataset or the calibration
    (reports.scene_fit.job.run_fit), so a [fit] naming a missing field is reported first:
    exit 2, one `error:` line naming the scene file and the field, no traceback."""
    scene = _scene_file(tmp_path, '"cd[3].center" = {}')
    dataset = tmp_path / "dataset"
    (dataset / "photos").mkdir(parents=True)
    status = main(["fit", str(dataset), "--scene", str(scene), "--calibration", str(tmp_path / "calibration.json"),
                   "--out", str(tmp_path / "fit")])
    captured = capsys.readouterr()
    assert status == 2
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error: ") and str(scene) in lines[0] and "field 'fit.cd[3].center'" in lines[0]
    assert "Traceback" not in captured.err
    assert not (tmp_path / "fit").exists()  # nothing written for a refused scene


def test_a_groove_width_is_fitted_about_the_stripes_centre(tmp_path):
    """``cd[0].structure.layers[0].shapes[0].width``: the pits' stripe (x = [0.5, 1.1] in cd.toml,
    0.6 um wide) with the default +-30 %; a fitted width goes into the structure copy about the
    stripe's centre (0.8 um), the period and depth unchanged."""
    source = _scene_file(tmp_path, '"cd[0].structure.layers[0].shapes[0].width" = {}\n')
    spec = load_scene(source)
    (width,) = _fit(spec).free
    assert width.kind == "width" and (width.layer, width.shape) == (0, 0)
    assert width.nominal == pytest.approx((0.6,), abs=EXACT)
    assert (width.lower, width.upper) == (pytest.approx((0.42,)), pytest.approx((0.78,)))
    out = tmp_path / "out"
    out.mkdir()
    fitted = load_scene(write_fitted_scene(spec, _fit(spec), np.array([0.66]), out, "a test"))
    stripe = load_structure(fitted.cds[0].structure).layers[0].shapes[0]
    assert (stripe.x0, stripe.x1) == (pytest.approx(0.47, abs=EXACT), pytest.approx(1.13, abs=EXACT))
    original = load_structure(spec.cds[0].structure)
    assert load_structure(fitted.cds[0].structure).period == original.period
    assert load_structure(fitted.cds[0].structure).layers[0].thickness == original.layers[0].thickness
