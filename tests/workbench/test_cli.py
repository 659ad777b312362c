"""`workbench rcwa solve`: output formats and clear errors for bad input (no tracebacks).

Each error must name the file, the field and what was expected; exit status 2.
"""

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from rcwa.materials import material_from_spec
from workbench.cli import main

DIRECTION_COSINE_TOL = 1e-9  # angles printed as float64 degrees: only round-off separates them from the equation

GOOD = textwrap.dedent("""\
    name = "grating"
    period = [1.6]
    superstrate = "polycarbonate"
    substrate = "aluminum"

    [[layers]]
    thickness = 0.11
    material = "polycarbonate"
    shapes = [ { material = "aluminum", x = [0.5, 1.1] } ]
""")


def _write(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_json_output_has_the_documented_fields(tmp_path, capsys):
    path = _write(tmp_path, GOOD)
    code, out, _ = _run(capsys, "rcwa", "solve", str(path), "--wavelength", "550", "--theta", "20", "--phi", "10",
                        "--orders", "31", "--pol", "p", "--json")
    assert code == 0
    data = json.loads(out)
    for key in ("wavelength_nm", "theta_deg", "phi_deg", "pol", "R_total", "T_total", "absorption", "orders"):
        assert key in data
    assert data["pol"] == "p" and data["wavelength_nm"] == 550.0
    fields = {"m", "n", "R", "T", "direction_R", "direction_T", "jones_R", "jones_T", "mueller_R", "mueller_T"}
    assert all(set(o) == fields and o["n"] == 0 for o in data["orders"])
    assert "M00 is the unpolarized efficiency" in data["polarimetry"]
    assert sum(o["R"] for o in data["orders"]) == pytest.approx(data["R_total"], abs=1e-12)
    assert "superstrate" in data["directions"] and "substrate" in data["directions"]


def test_json_directions_follow_the_grating_equation(tmp_path, capsys):
    """Reflected order m leaves with tangential direction cosines (in the superstrate)
    sin(theta_m) (cos phi_m, sin phi_m) = sin(theta) (cos phi, sin phi) - (m lambda / (n1 Lambda), 0)
    (Lange et al. 2021 Eq. 2 sign); over aluminium nothing is transmitted."""
    path = _write(tmp_path, GOOD)
    wavelength, theta, phi = 550.0, 20.0, 10.0
    code, out, _ = _run(capsys, "rcwa", "solve", str(path), "--wavelength", str(wavelength), "--theta", str(theta),
                        "--phi", str(phi), "--orders", "31", "--json")
    assert code == 0
    n1 = float(np.sqrt(material_from_spec("polycarbonate").epsilon(np.array([wavelength]))[0]).real)
    for order in json.loads(out)["orders"]:
        assert order["direction_T"] is None
        t, p = np.radians(order["direction_R"]["theta_deg"]), np.radians(order["direction_R"]["phi_deg"])
        ux = np.sin(np.radians(theta)) * np.cos(np.radians(phi)) - order["m"] * wavelength / 1000 / (n1 * 1.6)
        uy = np.sin(np.radians(theta)) * np.sin(np.radians(phi))
        assert np.sin(t) * np.cos(p) == pytest.approx(ux, abs=DIRECTION_COSINE_TOL)
        assert np.sin(t) * np.sin(p) == pytest.approx(uy, abs=DIRECTION_COSINE_TOL)


def test_table_output_for_builtin_2d(capsys):
    code, out, _ = _run(capsys, "rcwa", "solve", "gold2d", "--wavelength", "550", "--orders", "5,5")
    assert code == 0 and "total R" in out and "gold2d" in out


BAD_FILES = {
    "malformed TOML": (GOOD.replace("period = [1.6]", "period = [1.6"), "not valid TOML", None),
    "unknown material": (GOOD.replace('substrate = "aluminum"', 'substrate = "unobtainium"'), "substrate", "unobtainium"),
    "negative thickness": (GOOD.replace("thickness = 0.11", "thickness = -0.11"), "layers[0].thickness", ">= 0"),
    "zero period": (GOOD.replace("period = [1.6]", "period = [0]"), "period[0]", "> 0"),
    "negative period": (GOOD.replace("period = [1.6]", "period = [-1.6]"), "period[0]", "> 0"),
    "stripe ends before it starts": (GOOD.replace("x = [0.5, 1.1]", "x = [1.1, 0.5]"), "layers[0].shapes[0].x", "x1 > x0"),
    "stripe wider than the period": (GOOD.replace("x = [0.5, 1.1]", "x = [0.0, 2.0]"), "layers[0].shapes[0].x", "<= 1.6"),
    "missing superstrate": (GOOD.replace('superstrate = "polycarbonate"\n', ""), "superstrate", "missing"),
    "2D shape in 1D": (
        GOOD.replace("x = [0.5, 1.1]", "rect = { center = [0, 0], size = [1, 1] }"), "layers[0].shapes[0].rect", "x = [x0, x1]"
    ),
}


@pytest.mark.parametrize("case", BAD_FILES)
def test_bad_structure_files(tmp_path, capsys, case):
    text, field, expected = BAD_FILES[case]
    path = _write(tmp_path, text)
    code, out, err = _run(capsys, "rcwa", "solve", str(path), "--wavelength", "550", "--orders", "11")
    assert code == 2 and out == ""
    assert err.startswith("error: ") and str(path) in err and field in err
    if expected:
        assert expected in err
    assert "Traceback" not in err


BAD_ARGUMENTS = {
    "theta of 90": (["--theta", "90"], "theta", "0 <= theta < 90"),
    "even orders": (["--orders", "10"], "orders", "odd"),
    "wavelength outside the data": (["--wavelength", "5000"], "superstrate", "has data for 360-1052 nm"),
    "two order counts for 1D": (["--orders", "11,11"], "orders", "1 order count"),
}


@pytest.mark.parametrize("case", BAD_ARGUMENTS)
def test_bad_arguments(tmp_path, capsys, case):
    extra, field, expected = BAD_ARGUMENTS[case]
    path = _write(tmp_path, GOOD)
    args = {"--wavelength": "550", "--orders": "11", "--theta": "10"}
    for k, v in zip(extra[::2], extra[1::2], strict=True):
        args[k] = v
    argv = ["rcwa", "solve", str(path)] + [x for kv in args.items() for x in kv]
    code, _, err = _run(capsys, *argv)
    assert code == 2 and field in err and expected in err and "Traceback" not in err


def test_wavelength_error_names_file_and_field(tmp_path, capsys):
    text = GOOD.replace('substrate = "aluminum"', 'substrate = "gold"')
    text = text.replace('superstrate = "polycarbonate"', 'superstrate = "air"')
    path = _write(tmp_path, text.replace('material = "polycarbonate"', 'material = "air"'))
    code, _, err = _run(capsys, "rcwa", "solve", str(path), "--wavelength", "3000", "--orders", "11")
    assert code == 2 and str(path) in err and "substrate" in err and "gold" in err


def test_2d_shape_larger_than_the_cell(tmp_path, capsys):
    text = textwrap.dedent("""\
        period = [1.0, 1.0]
        superstrate = "air"
        substrate = "air"
        [[layers]]
        thickness = 0.2
        material = "air"
        shapes = [ { material = "gold", circle = { center = [0.5, 0.5], radius = 0.6 } } ]
    """)
    path = _write(tmp_path, text)
    code, _, err = _run(capsys, "rcwa", "solve", str(path), "--wavelength", "550", "--orders", "5,5")
    assert code == 2 and "layers[0].shapes[0].circle" in err and "larger than the unit cell" in err


def test_unknown_structure_name(capsys):
    code, _, err = _run(capsys, "rcwa", "solve", "no_such_thing", "--wavelength", "550", "--orders", "11")
    assert code == 2 and "cd" in err and "gold2d" in err


def test_installed_command_prints_no_traceback(tmp_path):
    path = _write(tmp_path, GOOD.replace("thickness = 0.11", "thickness = -1"))
    proc = subprocess.run([sys.executable, "-m", "workbench.cli", "rcwa", "solve", str(path), "--wavelength", "550",
                           "--orders", "11"], capture_output=True, text=True)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr and "thickness" in proc.stderr


def test_the_pose_summary_line_states_the_scene_edges_found() -> None:
    """calibrate pose and calibrate DATASET print each photo's coverage (the goodness-of-fit test that
    refuses a photo of something else below 0.75), so a user sees how near a photo came to it."""
    from workbench.commands.calibrate import pose_summary_line

    photo = {"std": {"camera_center_m": [1e-4, 2e-4, 3e-4], "rotation_total_deg": 0.01},
             "camera": {"camera_center_m": [0.278, 0.27, -0.8], "fov_x_deg": 39.3},
             "residuals": {"robust_sigma_px": 0.31, "points": 900, "coverage": 0.934}, "exposure_scale": None}
    line = pose_summary_line("view0.dng", photo)
    assert "93 % of the scene's edges found" in line and "\n" not in line
    del photo["residuals"]["coverage"]  # a record written before coverage was kept
    assert "edges found" not in pose_summary_line("view0.dng", photo)
