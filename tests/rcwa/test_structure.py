"""rcwa/structure.py: the structure file format (docs/structure_format.md).

What a file means: its fields, shapes and materials as parsed; that stripes wrap across
the cell edge and later shapes paint over earlier ones (checked by solving: a structure and
its explicit equivalent give the same efficiencies); the built-ins. What a bad file does:
a UserInputError carrying the file and the dotted field (the command line's rendering of
such errors is tested in tests/workbench/test_cli.py).

Tolerance: TOLERANCE_EQUIVALENT = 1e-12 on efficiencies of two descriptions of the same
cell. A painted-over shape and its explicit pieces have identical Fourier coefficients up
to round-off; a translated cell multiplies coefficient g by a phase, a unitary similarity
of the layer's eigenproblem that changes no efficiency. Round-off only (measured ~1e-15).
"""

from __future__ import annotations

import hashlib
import textwrap
from pathlib import Path

import numpy as np
import pytest

import rcwa
from rcwa.shapes import Circle, Polygon, Rect, Stripe
from rcwa.structure import BUILTIN_STRUCTURES, Structure, load_structure
from tests.rcwa.helpers import nk, structure
from workbench.core.errors import UserInputError

TOLERANCE_EQUIVALENT = 1e-12

GOOD_2D = textwrap.dedent("""\
    name = "pillars"
    period = [1.0, 0.8]
    superstrate = "air"
    substrate = 1.5

    [[layers]]
    thickness = 0.2
    material = "air"
    shapes = [
      { material = { n = 2.0, k = 0.1 }, rect = { center = [0.3, 0.4], size = [0.2, 0.3] } },
      { material = "gold", circle = { center = [0.7, 0.4], radius = 0.15 } },
      { material = 1.8, polygon = [[0.1, 0.1], [0.3, 0.1], [0.2, 0.3]] },
    ]

    [[layers]]
    thickness = 0.0
    material = { file = "film.csv" }
""")
FILM_CSV = "wavelength_nm,n,k\n400,2.0,0.02\n700,1.8,0.01\n"


@pytest.fixture
def good_file(tmp_path: Path) -> Path:
    (tmp_path / "film.csv").write_text(FILM_CSV)
    path = tmp_path / "pillars.toml"
    path.write_text(GOOD_2D)
    return path


# ---------------------------------------------------------------- what a file means


def test_a_2d_file_parses_into_its_shapes_and_materials(good_file):
    s = Structure.from_toml(good_file)
    assert (s.name, s.period, s.dimension, s.source) == ("pillars", (1.0, 0.8), 2, str(good_file))
    assert [layer.thickness for layer in s.layers] == [0.2, 0.0]
    rect, circle, polygon = s.layers[0].shapes
    assert isinstance(rect, Rect) and (rect.center, rect.size) == ((0.3, 0.4), (0.2, 0.3))
    assert isinstance(circle, Circle) and (circle.center, circle.radius) == ((0.7, 0.4), 0.15)
    assert isinstance(polygon, Polygon) and polygon.vertices == ((0.1, 0.1), (0.3, 0.1), (0.2, 0.3))
    assert complex(rect.material.refractive_index(550.0)) == 2.0 + 0.1j
    assert circle.material.name == "gold" and complex(polygon.material.refractive_index(550.0)) == 1.8
    assert s.layers[1].is_uniform and not s.layers[0].is_uniform


def test_a_csv_material_is_found_beside_the_structure_file(good_file, monkeypatch, tmp_path):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # relative to the file, not to the working directory
    film = Structure.from_toml(good_file).layers[1].material
    np.testing.assert_allclose(film.refractive_index([400.0, 700.0]), [2.0 + 0.02j, 1.8 + 0.01j])


def test_name_defaults_to_the_file_stem_and_the_hash_is_of_the_text(good_file):
    good_file.write_text(GOOD_2D.replace('name = "pillars"\n', ""))
    s = Structure.from_toml(good_file)
    assert s.name == "pillars" and s.text == good_file.read_text()
    assert s.content_hash == hashlib.sha256(s.text.encode()).hexdigest()
    assert Structure.from_toml_string(GOOD_2D.replace("0.2", "0.25"), base_dir=good_file.parent).content_hash != s.content_hash


def test_a_dict_round_trips_through_its_toml_text():
    data = {"name": "g", "period": [1.2], "superstrate": "air", "substrate": {"n": 1.5, "k": 0.0},
            "layers": [{"thickness": 0.3, "material": 1.0, "shapes": [{"material": "gold", "x": [0.1, 0.5]}]}]}
    s = Structure.from_dict(data)
    again = Structure.from_toml_string(s.text)
    assert (again.name, again.period, again.layers, again.substrate) == (s.name, s.period, s.layers, s.substrate)
    assert isinstance(s.layers[0].shapes[0], Stripe)


def test_field_of_names_where_a_material_is_used_first(good_file):
    s = Structure.from_toml(good_file)
    assert s.field_of(s.superstrate) == "superstrate" and s.field_of(s.substrate) == "substrate"
    assert s.field_of(s.layers[0].shapes[1].material) == "layers[0].shapes[1].material"
    assert s.field_of(s.layers[1].material) == "layers[1].material"


@pytest.mark.parametrize("name", BUILTIN_STRUCTURES)
def test_builtins_load_by_name(name):
    s = load_structure(name)
    assert s.name == name and s.source == f"<built-in {name}>" and s.layers
    assert s.dimension == {"cd": 1, "gold2d": 2}[name]


def _efficiencies(s, orders=31):
    r = rcwa.solve(s, 550.0, 20.0, 35.0, orders, "s")
    return np.concatenate([r.all_orders["R"].ravel(), r.all_orders["T"].ravel()])


def _grating(stripes):
    return structure([1.0], nk(1.0), nk(1.5), [{"thickness": 0.4, "material": nk(1.0), "shapes": stripes}])


def test_a_stripe_across_the_cell_edge_wraps():
    """[0.8, 1.25] in a 1 um cell is [0.8, 1) and [0, 0.25): the stripe [0.2, 0.65] moved by
    0.6 um, the same grating."""
    wrapped = _grating([{"material": nk(2.0, 0.1), "x": [0.8, 1.25]}])
    inside = _grating([{"material": nk(2.0, 0.1), "x": [0.2, 0.65]}])
    split = _grating([{"material": nk(2.0, 0.1), "x": [0.8, 1.0]}, {"material": nk(2.0, 0.1), "x": [0.0, 0.25]}])
    assert np.abs(_efficiencies(wrapped) - _efficiencies(inside)).max() < TOLERANCE_EQUIVALENT
    assert np.abs(_efficiencies(wrapped) - _efficiencies(split)).max() < TOLERANCE_EQUIVALENT


def test_later_stripes_paint_over_earlier_ones():
    painted = _grating([{"material": nk(2.0), "x": [0.0, 0.8]}, {"material": nk(1.3), "x": [0.2, 0.4]}])
    pieces = _grating([{"material": nk(2.0), "x": [0.0, 0.2]}, {"material": nk(1.3), "x": [0.2, 0.4]},
                       {"material": nk(2.0), "x": [0.4, 0.8]}])
    reversed_order = _grating([{"material": nk(1.3), "x": [0.2, 0.4]}, {"material": nk(2.0), "x": [0.0, 0.8]}])
    assert np.abs(_efficiencies(painted) - _efficiencies(pieces)).max() < TOLERANCE_EQUIVALENT
    assert np.abs(_efficiencies(painted) - _efficiencies(reversed_order)).max() > 1e-4  # the order matters


def test_later_rectangles_paint_over_earlier_ones():
    def cell(shapes):
        return structure([1.0, 1.0], nk(1.0), nk(1.5), [{"thickness": 0.3, "material": nk(1.0), "shapes": shapes}])

    def rect(n, x0, x1, y0, y1):
        return {"material": nk(n), "rect": {"center": [(x0 + x1) / 2, (y0 + y1) / 2], "size": [x1 - x0, y1 - y0]}}

    painted = cell([rect(2.0, 0.0, 0.6, 0.0, 0.6), rect(1.4, 0.2, 0.4, 0.2, 0.4)])
    pieces = cell([rect(2.0, 0.0, 0.6, 0.0, 0.2), rect(2.0, 0.0, 0.2, 0.2, 0.4), rect(1.4, 0.2, 0.4, 0.2, 0.4),
                   rect(2.0, 0.4, 0.6, 0.2, 0.4), rect(2.0, 0.0, 0.6, 0.4, 0.6)])
    assert np.abs(_efficiencies(painted, (7, 7)) - _efficiencies(pieces, (7, 7))).max() < TOLERANCE_EQUIVALENT


# ---------------------------------------------------------------- what a bad file does

BAD_FILES = {
    # name: (replace this, by this, the field named, words of the message)
    "unknown top-level field": ('name = "pillars"', 'colour = "red"', "colour", "unknown field"),
    "misspelt layer field": ("thickness = 0.2", "thicknes = 0.2", "layers[0].thicknes", "unknown field"),
    "shapes not a list": ('{ file = "film.csv" }', '{ file = "film.csv" }\nshapes = "rect"', "layers[1].shapes",
                          "list of shape tables"),
    "shape not a table": ("shapes = [\n", 'shapes = [ "rect",\n', "layers[0].shapes[0]", "must be a table"),
    "two geometries": ("size = [0.2, 0.3] }", "size = [0.2, 0.3] }, circle = { center = [0, 0], radius = 0.1 }",
                       "layers[0].shapes[0]", "exactly one geometry"),
    "no geometry": (", rect = { center = [0.3, 0.4], size = [0.2, 0.3] }", "", "layers[0].shapes[0]", "exactly one geometry"),
    "rectangle without size": (", size = [0.2, 0.3]", "", "layers[0].shapes[0].rect.size", "missing"),
    "rectangle of zero width": ("size = [0.2, 0.3]", "size = [0.0, 0.3]", "layers[0].shapes[0].rect.size", "positive"),
    "rectangle with an angle": ("size = [0.2, 0.3]", "size = [0.2, 0.3], angle = 4", "layers[0].shapes[0].rect.angle",
                                "unknown field"),
    "centre of three numbers": ("center = [0.3, 0.4]", "center = [0.3, 0.4, 0.0]", "layers[0].shapes[0].rect.center",
                                "2 numbers"),
    "rectangle taller than the cell": ("size = [0.2, 0.3]", "size = [0.2, 0.9]", "layers[0].shapes[0].rect",
                                       "larger than the unit cell"),
    "negative radius": ("radius = 0.15", "radius = -0.15", "layers[0].shapes[1].circle.radius", "positive"),
    "polygon of two vertices": ("[[0.1, 0.1], [0.3, 0.1], [0.2, 0.3]]", "[[0.1, 0.1], [0.3, 0.1]]",
                                "layers[0].shapes[2].polygon", "at least 3 vertices"),
    "self-crossing polygon": ("[[0.1, 0.1], [0.3, 0.1], [0.2, 0.3]]", "[[0.1, 0.1], [0.3, 0.3], [0.3, 0.1], [0.1, 0.3]]",
                              "layers[0].shapes[2].polygon", "simple"),
    "vertex of three numbers": ("[0.2, 0.3]]", "[0.2, 0.3, 1.0]]", "layers[0].shapes[2].polygon[2]", "2 numbers"),
    "stripe in a 2D cell": ("rect = { center = [0.3, 0.4], size = [0.2, 0.3] }", "x = [0.1, 0.2]",
                            "layers[0].shapes[0].x", "takes rect, circle or polygon"),
    "three periods": ("period = [1.0, 0.8]", "period = [1.0, 0.8, 0.5]", "period", "one or two lengths"),
    "period as a string": ("period = [1.0, 0.8]", 'period = "1.0"', "period", "one or two lengths"),
    "no period": ("period = [1.0, 0.8]\n", "", "period", "missing"),
    "name not a string": ('name = "pillars"', "name = 3", "name", "string"),
    "thickness as a string": ("thickness = 0.2", 'thickness = "0.2"', "layers[0].thickness", "number"),
    "negative k in a shape": ("k = 0.1", "k = -0.1", "layers[0].shapes[0].material.k", "out of range"),
    "unknown layer material": ('material = "air"', 'material = "vacuum"', "layers[0].material", "unknown material"),
    "no substrate": ("substrate = 1.5\n", "", "substrate", "missing"),
}


@pytest.mark.parametrize("case", BAD_FILES)
def test_a_bad_file_is_an_error_naming_file_and_field(good_file, case):
    old, new, field, words = BAD_FILES[case]
    assert old in GOOD_2D
    good_file.write_text(GOOD_2D.replace(old, new, 1))
    with pytest.raises(UserInputError) as info:
        Structure.from_toml(good_file)
    error = info.value
    assert (error.file, error.field) == (str(good_file), field) and words in error.reason
    assert str(error).startswith(f"{good_file}: field '{field}': ")


def test_a_bad_csv_material_names_the_csv_file(good_file):
    csv = good_file.parent / "film.csv"
    csv.write_text("wavelength_nm,n,k\n400,2.0,-0.02\n700,1.8,0.01\n")
    with pytest.raises(UserInputError) as info:
        Structure.from_toml(good_file)
    assert info.value.field == "layers[1].material" and "line 2" in str(info.value)
    assert str(csv) in str(info.value)


def test_invalid_toml_names_the_file(good_file):
    good_file.write_text(GOOD_2D.replace("period = [1.0, 0.8]", "period = [1.0, 0.8"))
    with pytest.raises(UserInputError, match="not valid TOML") as info:
        Structure.from_toml(good_file)
    assert info.value.file == str(good_file)


def test_a_missing_file_names_the_file(tmp_path):
    with pytest.raises(UserInputError) as info:
        Structure.from_toml(tmp_path / "absent.toml")
    assert info.value.file == str(tmp_path / "absent.toml")


@pytest.mark.parametrize("layers, field", [([1], "layers[0]"), ({"thickness": 1.0}, "layers")])
def test_a_bad_dict_names_its_source(layers, field):
    with pytest.raises(UserInputError) as info:
        Structure.from_dict({"period": [1.0], "superstrate": "air", "substrate": "air", "layers": layers}, source="<api>")
    assert (info.value.file, info.value.field) == ("<api>", field)
