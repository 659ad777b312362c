"""Property-based: the command line given generated and mutated inputs ends with exit 0, or exit 2 and
one `error:` line, never a traceback (issue 45, item 2; issue 46, item 7).

Inputs start from files the workbench really reads (the built-in CD structure, the built-in scene, a
PNG, a JPEG and a DNG the synthetic sensor writes, the calibration.json `calibrate DATASET` wrote for
the suite's shared dataset) and are mutated by hypothesis: a number replaced by
any float (inf, nan, huge, negative, zero) or integer, a line deleted or duplicated, text inserted, bytes
flipped or the file truncated. Settings (``SETTINGS``): derandomized (the same examples every run),
no deadline; EXAMPLES per command. What it found while it was built is in docs/testing.md.
"""

from __future__ import annotations

import functools
import io
import re
import tempfile
import traceback
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from datasets_synthetic.dng import DngMetadata, write_dng
from renderer.scene import load_scene
from workbench.cli import main

ROOT = Path(__file__).resolve().parents[2]
CD_TEXT = (ROOT / "rcwa" / "structures" / "cd.toml").read_text()
EXAMPLES = {"structure": 60, "scene": 12, "image": 40, "calibration": 150}
SETTINGS = dict(derandomize=True, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                        HealthCheck.too_slow])
NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e-?\d+)?(?![\w.])")

values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(min_value=-10**30, max_value=10**30),
                   st.sampled_from(["0", "-0.0", "1e308", "1e-308", '"text"', "[]", "[1, 2, 3]", "{}", "true"]))


@st.composite
def mutated_text(draw, text: str) -> str:
    """``text`` with one mutation (module docstring)."""
    lines = text.splitlines()
    kind = draw(st.sampled_from(["number", "number", "delete", "duplicate", "insert"]))
    if kind == "number":
        spots = list(NUMBER.finditer(text))
        spot = spots[draw(st.integers(0, len(spots) - 1))]
        value = draw(values)
        literal = value if isinstance(value, str) else ("nan" if value != value else
                                                        ("inf" if value == float("inf") else
                                                         ("-inf" if value == float("-inf") else repr(value))))
        return text[:spot.start()] + literal + text[spot.end():]
    at = draw(st.integers(0, len(lines) - 1))
    if kind == "delete":
        return "\n".join(lines[:at] + lines[at + 1:])
    if kind == "duplicate":
        return "\n".join(lines[:at + 1] + lines[at:])
    return "\n".join(lines[:at] + [draw(st.text(max_size=40))] + lines[at:])


def _command(args: list[str], capsys) -> tuple[int, str]:
    try:
        code = main(args)
    except SystemExit as exit_:
        code = int(exit_.code or 0)
    except Exception:  # noqa: BLE001 - a traceback is the failure this test looks for
        pytest.fail(f"{' '.join(args)}: traceback\n{traceback.format_exc()}")
    return code, capsys.readouterr().err


def _one_line_or_success(code: int, err: str) -> None:
    assert code in (0, 2), err
    if code == 2:
        errors = [line for line in err.splitlines() if line.startswith("error: ")]
        assert len(errors) == 1 and "Traceback" not in err, err


@settings(max_examples=EXAMPLES["structure"], **SETTINGS)
@given(text=mutated_text(CD_TEXT))
def test_mutated_structures(tmp_path, capsys, text):
    path = tmp_path / "s.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    _one_line_or_success(*_command(["rcwa", "solve", str(path), "--wavelength", "550", "--theta", "10",
                                    "--orders", "5", "--json"], capsys))


@pytest.mark.slow
@settings(max_examples=EXAMPLES["scene"], **SETTINGS)
@given(text=mutated_text(load_scene("cornell_cd").text))
def test_mutated_scenes(tmp_path, capsys, text):
    path = tmp_path / "scene.toml"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    _one_line_or_success(*_command(["plan", str(path), "--json"], capsys))


@functools.cache
def _seed_images() -> dict[str, bytes]:
    rng = np.random.default_rng(0)
    pixels = (rng.random((32, 48, 3)) * 255).astype(np.uint8)
    out = {}
    for fmt in ("png", "jpeg"):
        buffer = io.BytesIO()
        Image.fromarray(pixels).save(buffer, format=fmt.upper())
        out[fmt] = buffer.getvalue()
    raw = (rng.random((32, 48)) * 15000 + 600).astype(np.uint16)
    with tempfile.TemporaryDirectory() as folder:
        out["dng"] = write_dng(Path(folder) / "seed.dng", raw, DngMetadata()).read_bytes()
    return out


@settings(max_examples=EXAMPLES["image"], **SETTINGS)
@given(fmt=st.sampled_from(["png", "jpeg", "dng"]), cut=st.floats(0.0, 1.0),
       flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(0, 255)), max_size=8))
def test_mutated_images(tmp_path_factory, capsys, fmt, cut, flips):
    folder = tmp_path_factory.mktemp("images")
    data = bytearray(_seed_images()[fmt])
    for where, byte in flips:
        data[int(where * (len(data) - 1))] = byte
    data = data[:max(1, int(len(data) * (1.0 if cut > 0.7 else cut)))]
    path = folder / f"photo.{fmt}"
    path.write_bytes(bytes(data))
    _one_line_or_success(*_command(["decode", str(path), "--out", str(folder / "out.exr")], capsys))


@functools.cache
def _calibration_text(path: str) -> str:
    """The file with this run's folder replaced by a fixed one, so the derandomized examples
    mutate the same numbers in every run (the folder's name holds digits)."""
    return Path(path).read_text().replace(str(Path(path).parents[1]), "/datasets/cornell_cd-seed0")


@pytest.fixture(scope="module")
def calibration_json(tmp_path_factory) -> str:
    from tests.calibration.test_pose import calibrated_dataset

    out, _, _ = calibrated_dataset(tmp_path_factory)
    return str(out / "calibration.json")


@pytest.mark.slow
@settings(max_examples=EXAMPLES["calibration"], **SETTINGS)
@given(data=st.data())
def test_mutated_calibration_files(tmp_path_factory, calibration_json, data):
    """Every reader of calibration.json (calibration.calibration_file, its one owner) returns or
    refuses with a UserInputError, which the command line prints as one line."""
    from calibration.calibration_file import exposure_relative_std, read_camera, read_response, vignetting_record
    from workbench.core.errors import UserInputError

    text = data.draw(mutated_text(_calibration_text(calibration_json)))
    path = tmp_path_factory.mktemp("calibration") / "calibration.json"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    for read in (lambda: read_camera(path, "view0.dng"), lambda: read_response(path),
                 lambda: exposure_relative_std(path, "view0.dng"), lambda: vignetting_record(path)):
        try:
            read()
        except UserInputError:
            pass
        except Exception:  # noqa: BLE001 - a traceback is the failure this test looks for
            pytest.fail(f"a mutated calibration.json (its start: {text[:300]!r}):\n{traceback.format_exc()}")
