"""Field validation shared by every file format (workbench/core/validation.py).

Each way a field or a user's file can be wrong is a UserInputError whose message names
the field (or the file), what was expected and what came; good values pass through as
the numbers the callers use.
"""

from __future__ import annotations

import pytest

from workbench.core.errors import UserInputError
from workbench.core.validation import (
    looks_like_path,
    number,
    pair,
    point,
    read_text_file,
    reject_unknown,
    required,
    vector,
)


def test_required_and_unknown_fields_are_named():
    assert required({"period": [1.0]}, "period", "") == [1.0]
    with pytest.raises(UserInputError, match=r"field 'layers\[0\]\.thickness': is missing"):
        required({}, "thickness", "layers[0].")
    with pytest.raises(UserInputError, match=r"field 'camera\.fvo': unknown field; expected one of \['fov', 'position'\]"):
        reject_unknown({"fov": 40, "fvo": 40}, {"fov", "position"}, "camera.")


@pytest.mark.parametrize(("value", "flags", "message"), [
    ("1.0", {}, "must be a number"),
    (True, {}, "must be a number"),  # TOML's true is not 1
    ([1.0], {}, "must be a number"),
    (0.0, {"positive": True}, "must be positive"),
    (-1e-9, {"nonnegative": True}, "must not be negative"),
    (float("inf"), {"nonnegative": True}, "must be a finite number"),  # issue 46, cause 11: thickness = inf
    (float("nan"), {}, "must be a finite number"),  # a scene's NaN CD centre
    (10**400, {}, "must be a finite number"),  # a TOML integer past a float's range
])
def test_bad_numbers_name_the_field_and_what_came(value, flags, message):
    with pytest.raises(UserInputError) as err:
        number(value, "light.power_w", **flags)
    text = str(err.value)
    assert "field 'light.power_w'" in text and message in text and repr(value) in text


def test_good_numbers_pass_as_floats():
    assert number(3, "x") == 3.0 and isinstance(number(3, "x"), float)
    assert number(0, "x", nonnegative=True) == 0.0
    assert pair([1, 2.5], "size", positive=True) == (1.0, 2.5)
    assert point([0, -1, 2], "camera.position") == (0.0, -1.0, 2.0)


def test_vectors_name_the_element_that_is_wrong():
    with pytest.raises(UserInputError, match=r"field 'camera\.position': must be a list of 3 numbers; expected \[x, y, z\]"):
        point([0, 1], "camera.position")
    with pytest.raises(UserInputError, match=r"field 'size\[1\]': must be positive"):
        pair([1.0, 0.0], "size", positive=True)
    with pytest.raises(UserInputError, match="expected 4 numbers"):
        vector((1, 2, 3, 4), "dist", 4)  # a tuple is not what TOML gives


def test_unusable_text_files_are_refused_naming_the_file(tmp_path):
    cases = {"missing.toml": None, "folder.toml": "dir", "binary.toml": b"\x00\xff\xfe", "empty.toml": b"# only\n\n  \n"}
    messages = {"missing.toml": "structure file not found", "folder.toml": "is a folder",
                "binary.toml": "not a text file: byte 0xff at offset 1", "empty.toml": "is empty"}
    for name, content in cases.items():
        path = tmp_path / name
        if content == "dir":
            path.mkdir()
        elif content is not None:
            path.write_bytes(content)
        with pytest.raises(UserInputError) as err:
            read_text_file(path, "structure")
        assert str(err.value).startswith(str(path)) and messages[name] in str(err.value), str(err.value)


def test_a_text_file_is_read_without_its_byte_order_mark(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes("\ufeffperiod = [1.0]\n".encode())
    assert read_text_file(path, "structure") == "period = [1.0]\n"


@pytest.mark.parametrize(("name", "is_path"), [
    ("cd", False), ("cornell_cd", False), ("cd.toml", True), ("./cd", True), ("dir\\cd", True), ("a/b", True),
])
def test_names_with_a_folder_or_suffix_are_paths(name, is_path):
    assert looks_like_path(name) is is_path
