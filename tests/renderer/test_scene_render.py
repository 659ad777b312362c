"""Scenes and `workbench render`.

* Spectral pipeline: a Lambertian patch of known reflectance rho under a uniform
  environment of radiance L (an LED spectrum) reflects rho * L; its camera-RGB value
  must equal sum over channels of the integral of rho L S_c computed here with numpy
  (independent of Mitsuba), within 1.5 % (Monte Carlo noise of the patch mean at this
  spp, about 0.3 %, plus the 5 nm spectral grids' quadrature, under 1 %).
* The built-in scene loads and renders: finite, positive, the EXR reads back, the sidecar
  records settings.
* A render killed after some passes resumes and equals an uninterrupted one.
* Bad scene files give clear errors naming the field.
"""

import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from renderer.scene import load_scene, parse_scene
from workbench.core.errors import UserInputError

TOLERANCE_SPECTRAL = 0.015


def test_patch_colour_equals_spectral_integration(mitsuba_variant):
    import colour
    import mitsuba as mi

    from renderer.build import irregular, sensor_dict
    from renderer.camera import CameraModel, look_at
    from renderer.scene import CameraSpec, cornell_data

    refl = cornell_data()["reflectance"]
    led = colour.SDS_ILLUMINANTS["LED-B3"]
    wl = np.arange(360.0, 831.0, 1.0)
    rho = np.interp(wl, refl["wavelength_nm"], refl["red"])  # held constant beyond 400-700, as the builder does
    L = np.interp(wl, led.wavelengths, led.values, left=0, right=0) / 100.0
    cam = CameraSpec(CameraModel.from_fov(32, 32, 30.0, look_at([0, 0, 2], [0, 0, 0], [0, 1, 0])), 1.0, "Nikon 5100 (NPL)")
    sensor, plan = sensor_dict(mi, cam, 512)
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": 2}, "sensor": sensor,
                          "patch": {"type": "rectangle", "bsdf": {"type": "diffuse", "reflectance": irregular(refl["wavelength_nm"], refl["red"])}},
                          "sky": {"type": "constant", "radiance": irregular(wl, L)}})
    image = cam.model.warp(np.array(mi.render(scene, seed=0)), plan)
    centre = image[8:24, 8:24].reshape(-1, 3).mean(axis=0)
    sens = colour.MSDS_CAMERA_SENSITIVITIES["Nikon 5100 (NPL)"]
    expected = [np.trapezoid(rho * L * np.interp(wl, sens.wavelengths, sens.values[:, c], left=0, right=0), wl) for c in range(3)]
    assert centre == pytest.approx(expected, rel=TOLERANCE_SPECTRAL)


def test_builtin_scene_renders(mitsuba_variant, tmp_path):
    import mitsuba as mi

    from renderer.render import render

    info = render("cornell_cd", tmp_path / "r.exr", spp=8, resolution=(96, 72), progress=False)
    image = np.array(mi.Bitmap(str(tmp_path / "r.exr")))
    assert image.shape == (72, 96, 3) and np.all(np.isfinite(image)) and image.mean() > 0
    side = json.loads((tmp_path / "r.json").read_text())
    assert side["spp"] == 8 and side["resolution"] == [96, 72] and side["tables"] and side["variant"] == info["variant"]
    assert (tmp_path / "r.png").stat().st_size > 0


def test_killed_render_resumes(tmp_path):
    out = tmp_path / "k.exr"
    cmd = [sys.executable, "-m", "workbench.cli", "render", "cornell_cd", "--out", str(out), "--spp", "512",
           "--resolution", "160x120", "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    partial = tmp_path / "k.exr.partial.npz"
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None and not partial.exists():
        time.sleep(0.02)
    assert proc.poll() is None, "the render finished before it could be killed"
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    resumed = subprocess.run(cmd, capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    side = json.loads((tmp_path / "k.json").read_text())
    assert side["resumed_passes"] >= 1 and not partial.exists()
    clean = subprocess.run([*cmd[:6], str(tmp_path / "c.exr"), *cmd[7:]], capture_output=True, text=True)
    assert clean.returncode == 0
    import mitsuba  # noqa: F401  (variant already set in the subprocesses; reading needs only Bitmap)
    from renderer.variant import set_variant

    set_variant()
    a = np.array(mitsuba.Bitmap(str(out)))
    b = np.array(mitsuba.Bitmap(str(tmp_path / "c.exr")))
    assert np.allclose(a, b, rtol=1e-5, atol=1e-7)


BASE = load_scene("cornell_cd").text


@pytest.mark.parametrize("edit, field", [
    (("[camera]\nresolution = [326, 245]\n", "[camera]\n"), "camera.resolution"),
    (("size = 0.040", "size = -0.040"), "glass[0].size"),
    (('material = "n-bk7"', 'material = "unobtainium"'), "glass[0].material"),
    (('origin = [0.278, 0.42, -0.55]', 'origin = [-0.2, 0.3, 0.3]'), "camera.look_at.origin"),
    (('structure = "cd"', 'structure = "no_such_grating.toml"'), "cd[0].structure"),
    (('power_w = 10.0', 'power_w = 0'), "light.power_w"),
    (('model = "cornell"', 'model = "cornell"\nsize = [0.6, -0.5, 0.6]'), "box.size[1]"),
    (('emission_profile = "lambertian"', 'emission_profile = { cos_power = -1 }'), "light.emission_profile.cos_power"),
    (('emission_profile = "lambertian"', 'emission_profile = { cos_power = inf }'), "light.emission_profile.cos_power"),
    (('emission_profile = "lambertian"', 'emission_profile = { cos_power = "2" }'), "light.emission_profile.cos_power"),
    (('emission_profile = "lambertian"', 'emission_profile = "spot"'), "light.emission_profile"),
    (('emission_profile = "lambertian"', 'emission_profile = { power = 2 }'), "light.emission_profile.power"),
    (('emission_profile = "lambertian"', 'emission_profile = {}'), "light.emission_profile.cos_power"),
    (('dispersion = true', 'dispersion = "yes"'), "glass[0].dispersion"),
    (('dispersion = false', 'dispersion = 0'), "cd[0].dispersion"),
])
def test_bad_scene_files(edit, field):
    old, new = edit
    assert old in BASE
    with pytest.raises(UserInputError) as err:
        parse_scene(BASE.replace(old, new), source="bad.toml", base_dir=None)
    assert "bad.toml" in str(err.value) and field in str(err.value)


def test_render_cli_errors(capsys):
    from workbench.cli import main

    assert main(["render", "nope", "--out", "x.exr"]) == 2
    assert "cornell_cd" in capsys.readouterr().err
    assert main(["render", "cornell_cd", "--out", "x.png"]) == 2
    assert ".exr" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["cornell_cd", "cornell_cd_view2", "grating2d_gold"])
def test_every_builtin_scene_renders(mitsuba_variant, tmp_path, name):
    """Each built-in scene (the paper's Figs. 4, 5 and 6) loads and renders finite, lit images."""
    import mitsuba as mi

    from renderer.render import render

    render(name, tmp_path / f"{name}.exr", spp=4, resolution=(48, 36), progress=False)
    image = np.array(mi.Bitmap(str(tmp_path / f"{name}.exr")))
    assert np.all(np.isfinite(image)) and image.mean() > 0


def test_dask_render_equals_local_render(mitsuba_variant, tmp_path):
    """Passes on two worker processes (loopback LocalCluster) give the local result: each
    pass has its own seed wherever it runs (float round-off tolerance)."""
    import mitsuba as mi

    from workbench.core.executor import DaskExecutor
    from renderer.render import render

    kwargs = dict(spp=192, resolution=(48, 36), progress=False)  # 3 passes of 64 spp
    render("cornell_cd", tmp_path / "local.exr", **kwargs)
    with DaskExecutor(workers=2) as executor:
        info = render("cornell_cd", tmp_path / "dask.exr", executor=executor, **kwargs)
    assert info["passes"] == 3
    a = np.array(mi.Bitmap(str(tmp_path / "local.exr")))
    b = np.array(mi.Bitmap(str(tmp_path / "dask.exr")))
    assert np.allclose(a, b, rtol=1e-4, atol=1e-6)


def test_box_size_rescales_the_measured_box(mitsuba_variant):
    """A 2x larger box: its walls are twice as far, and the camera check follows it."""
    import mitsuba as mi

    from renderer.build import scene_dict

    text = BASE.replace('model = "cornell"', 'model = "cornell"\nsize = [1.112, 1.0976, 1.1184]')
    spec = parse_scene(text, source="big.toml", base_dir=None)
    d, _ = scene_dict(mi, spec, spp=1)
    bbox = mi.load_dict({"type": "scene", "floor": d["floor_white_0"]}).bbox()
    assert np.allclose([bbox.max.x, bbox.max.z], [1.1056, 1.1184], atol=1e-4)
