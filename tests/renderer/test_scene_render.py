"""Scenes and `workbench render`.

* Spectral pipeline: a Lambertian patch of known reflectance rho under a uniform
  environment of radiance L (an LED spectrum) reflects rho * L; its camera-RGB value
  must equal sum over channels of the integral of rho L S_c computed here with numpy
  (independent of Mitsuba), within 1.5 % (Monte Carlo noise of the patch mean at this
  spp, about 0.3 %, plus the 5 nm spectral grids' quadrature, under 1 %).
* The built-in scene loads and renders: finite, positive, the EXR reads back, the sidecar
  records settings.
* The built scene is the physical one (cornell_cd, direct lighting): on the floor, the back
  wall and the two side walls, each channel of the rendered image equals, region by region,
  what the light's radiance (power / (pi A), its spectrum), the measured reflectance and
  the camera's sensitivities give for each pixel's point through the light rectangle's
  irradiance integral (cos cos / r^2 over its area, numpy quadrature), within
  TOLERANCE_DIRECT = 1 % at DIRECT_SPP = 256 (the Monte Carlo noise of the region means,
  measured over 12 render seeds at 64 spp: up to 0.19 % (the red wall's red channel, cos^3
  profile), quadrature bias <= 0.05 %, so at 64 spp the bound was 5.0 SD, about 3e-7 false
  alarms per run with an uncertain tail; at 256 spp the noise halves: >= 9.5 SD, 2 profiles
  x 12 region-channels x Q(9.5) ~ 1e-19; pixels at region borders are left out, their
  footprint mixes surfaces). A wrong
  light power, position or size, swapped or wrong wall colours, wrong sensitivities or
  exposure fail it; and the red wall (x = 0.55 m) must be on the image's left, the green
  one on its right (the camera's handedness). Lambertian and cos^3 emission profiles.
* The CD splits colours where a flat mirror does not: under path tracing, the spread of
  the chromaticity over the CD's brighter pixels is at least CHROMA_SPREAD_RATIO = 5 times
  that of the same disk made of aluminium (Mitsuba's conductor; measured 0.058 against
  0.004, which is noise: aluminium reflects the white box almost neutrally, while the
  orders send each wavelength its own way).
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
# Noise (issue 23): the patch mean's Monte Carlo noise, measured over 200 render seeds: ratio - 1 per channel
# -1.5e-4 .. 2e-5 (the quadrature's share, well under the 1 % allowed) +- 8e-4 .. 1.4e-3, worst 5.1e-3 (3.6 SD);
# the bound is >= 10.3 SD: 3 channels x 2 sides x Q(10.3) ~ 1e-24 per run. Still caught: a 1.5 % error in a
# channel (a wrong sensitivity, spectrum or exposure scale). test_direct_light_equals_the_analytic_irradiance
# (TOLERANCE_DIRECT) and test_cd_splits_colours_unlike_a_flat_mirror are not yet measured over seeds.
TOLERANCE_DIRECT = 0.01
DIRECT_SPP = 256
# The CD's chromaticity spread is signal (0.058), the aluminium disk's noise (0.004 over ~75 bright pixels x 3
# channels at 256 spp, itself uncertain by ~5 %): the ratio 14.5 against 5 would need the noise 2.9x its
# expectation, over 30 SD: no false alarm from noise (issue 23). A CD rendered as a plain mirror fails it.
CHROMA_SPREAD_RATIO = 5.0
PHYSICS_RESOLUTION = (160, 120)


def test_patch_colour_equals_spectral_integration(mitsuba_variant):
    import colour
    import mitsuba as mi

    from renderer.camera import CameraModel, look_at
    from renderer.mitsuba_scene import sensor_dict
    from renderer.scene import CameraSpec, cornell_data
    from renderer.spectra import irregular

    refl = cornell_data()["reflectance"]
    led = colour.SDS_ILLUMINANTS["LED-B3"]
    wl = np.arange(360.0, 831.0, 1.0)
    rho = np.interp(wl, refl["wavelength_nm"], refl["red"])  # held constant beyond 400-700, as the builder does
    L = np.interp(wl, led.wavelengths, led.values, left=0, right=0) / 100.0
    cam = CameraSpec(CameraModel.from_fov(32, 32, 30.0, look_at([0, 0, 2], [0, 0, 0], [0, 1, 0])), 1.0, "Nikon 5100 (NPL)")
    sensor, plan = sensor_dict(mi, cam, 512)
    scene = mi.load_dict({"type": "scene", "integrator": {"type": "path", "max_depth": 2}, "sensor": sensor,
                          "patch": {"type": "rectangle",
                                    "bsdf": {"type": "diffuse", "reflectance": irregular(refl["wavelength_nm"], refl["red"])}},
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


def _primary_hits(mi, scene):
    """Each film pixel's primary hit: point, normal turned toward the camera, validity."""
    from renderer.accuracy import primary_hits

    si, ray, (H, W) = primary_hits(mi, scene)
    p, n, d = (np.array(v).T.reshape(H, W, 3) for v in (si.p, si.n, ray.d))
    n = n * np.sign(np.sum(-d * n, axis=-1, keepdims=True))
    return p, n, np.array(si.is_valid()).reshape(H, W)


def _box_regions(spec, p, n, valid):
    """Pixels of the floor, back wall and side walls, found by geometry (not by the
    builder's names), away from the objects' shadows and from region borders."""
    from scipy.ndimage import binary_erosion

    regions = {
        "floor": valid & (n[..., 1] > 0.9) & (p[..., 1] < 3e-4),
        "back wall": valid & (n[..., 2] < -0.9) & (p[..., 2] > 0.5),
        "left wall (x = 0.55 m)": valid & (np.abs(n[..., 0]) > 0.9) & (p[..., 0] > 0.5),
        "right wall (x = 0)": valid & (np.abs(n[..., 0]) > 0.9) & (p[..., 0] < 0.05),
    }
    for obj in [*spec.glass, *spec.cds]:  # shadows and the objects themselves
        c = np.asarray(obj.center)
        regions["floor"] &= np.hypot(p[..., 0] - c[0], p[..., 2] - c[2]) > 0.1
    return {name: binary_erosion(mask) for name, mask in regions.items()}


def _light_irradiance_factor(light_bbox, points, normals, cos_power=0.0, n=48):
    """Integral over the (downward-facing, horizontal) light rectangle of cos(theta_p)
    cos(theta_l)^(1 + cos_power) / r^2 dA for each point (midpoint rule, n x n); the
    emitted radiance is L0 cos(theta_l)^cos_power (renderer.emitter)."""
    lo, hi = np.asarray(light_bbox.min), np.asarray(light_bbox.max)
    gx = lo[0] + (np.arange(n) + 0.5) / n * (hi[0] - lo[0])
    gz = lo[2] + (np.arange(n) + 0.5) / n * (hi[2] - lo[2])
    lx, lz = np.meshgrid(gx, gz)
    nodes = np.stack([lx.ravel(), np.full(n * n, lo[1]), lz.ravel()], axis=1)
    out = np.empty(len(points))
    for start in range(0, len(points), 1024):
        to_light = nodes[None] - points[start:start + 1024, None]
        r2 = np.sum(to_light**2, axis=-1)
        cos_p_r = np.clip(np.sum(to_light * normals[start:start + 1024, None], axis=-1), 0.0, None)
        cos_l = np.clip(to_light[..., 1], 0.0, None) / np.sqrt(r2)
        out[start:start + 1024] = np.sum(cos_p_r * cos_l ** (1.0 + cos_power) / r2**1.5, axis=-1)
    return out * (hi[0] - lo[0]) * (hi[2] - lo[2]) / n**2


@pytest.mark.parametrize("profile", ['"lambertian"', "{ cos_power = 3 }"])
def test_direct_light_equals_the_analytic_irradiance(mitsuba_variant, profile):
    import mitsuba as mi

    from renderer.mitsuba_scene import light_dict, scene_dict
    from renderer.render import with_resolution
    from renderer.scene import cornell_data
    from renderer.spectra import camera_sensitivities, light_spectrum

    text = BASE.replace('emission_profile = "lambertian"', f"emission_profile = {profile}")
    spec = with_resolution(parse_scene(text, source="cornell_cd", base_dir=None), PHYSICS_RESOLUTION)
    d, _ = scene_dict(mi, spec, spp=DIRECT_SPP, integrator="direct")
    scene = mi.load_dict(d)
    image = np.array(mi.render(scene, seed=0))
    p, n, valid = _primary_hits(mi, scene)
    bbox = mi.load_dict(light_dict(mi, spec.light)).bbox()
    area = (bbox.max.x - bbox.min.x) * (bbox.max.z - bbox.min.z)
    assert area == pytest.approx(spec.light.size[0] * spec.light.size[1], rel=1e-4)
    wl = np.arange(360.0, 831.0, 1.0)
    lw, ls = light_spectrum(spec.light.spectrum)
    shape = np.interp(wl, lw, ls)
    cos_power = spec.light.cos_power or 0.0  # None: Lambertian
    # Radiance along the normal: P = L0 A 2 pi / (n + 2) (pi A L0 for a Lambertian light).
    radiance = shape * spec.light.power_w / (2 * np.pi / (cos_power + 2) * area * np.trapezoid(shape, wl))
    sens = [np.interp(wl, w, s) for w, s in camera_sensitivities(spec.camera.sensitivities)]
    refl = cornell_data()["reflectance"]
    colours = {"floor": "white", "back wall": "white", "left wall (x = 0.55 m)": "red", "right wall (x = 0)": "green"}
    regions = _box_regions(spec, p, n, valid)
    for name, mask in regions.items():
        assert mask.sum() > 1000, name  # each region is well covered at this resolution
        rho = np.interp(wl, refl["wavelength_nm"], refl[colours[name]])
        per_unit = np.array([np.trapezoid(rho / np.pi * radiance * s, wl) for s in sens]) * spec.camera.exposure
        expected = _light_irradiance_factor(bbox, p[mask], n[mask], cos_power)[:, None] * per_unit
        ratio = image[mask].sum(axis=0) / expected.sum(axis=0)
        assert ratio == pytest.approx(np.ones(3), abs=TOLERANCE_DIRECT), (name, ratio)
    columns = np.mgrid[0:valid.shape[0], 0:valid.shape[1]][1]
    width = valid.shape[1]
    assert columns[regions["left wall (x = 0.55 m)"]].mean() < width / 3
    assert columns[regions["right wall (x = 0)"]].mean() > 2 * width / 3


def test_cd_splits_colours_unlike_a_flat_mirror(mitsuba_variant):
    import mitsuba as mi

    from renderer.accuracy import element_crop
    from renderer.mitsuba_scene import scene_dict
    from renderer.render import with_resolution

    spec = with_resolution(load_scene("cornell_cd"), PHYSICS_RESOLUTION)
    ((x0, y0), (w, h)), mask = element_crop(mi, spec)
    assert mask.sum() > 150  # the CD's pixels at this resolution
    spread = {}
    for name, bsdf in (("cd", None), ("aluminium", {"type": "conductor", "material": "Al"})):
        d, _ = scene_dict(mi, spec, spp=256)
        if bsdf is not None:
            d["cd0"]["bsdf"] = bsdf
        d["sensor"]["film"].update(crop_offset_x=x0, crop_offset_y=y0, crop_width=w, crop_height=h)
        pixels = np.array(mi.render(mi.load_dict(d), seed=3))[mask]
        total = pixels.sum(axis=1)
        bright = total > np.median(total)
        spread[name] = float((pixels[bright] / total[bright, None]).std(axis=0).mean())
    assert spread["cd"] > CHROMA_SPREAD_RATIO * spread["aluminium"], spread


# Only a guard against a hang: the render (4 passes of 32 spp, ~1 s each) writes its first partial pass in
# seconds (its tables come from the suite's cache); the wait ends on that file, never on the clock (issue 23).
HANG_GUARD_S = 900.0


def test_killed_render_resumes(tmp_path):
    out = tmp_path / "k.exr"
    cmd = [sys.executable, "-m", "workbench.cli", "render", "cornell_cd", "--out", str(out), "--spp", "128",
           "--resolution", "160x120", "--quiet"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    partial = tmp_path / "k.exr.partial.npz"
    deadline = time.time() + HANG_GUARD_S
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
    (('power_w = 10.0', 'power_w = 1e308'), "light.power_w"),
    (('power_w = 10.0', 'power_w = 1e-46'), "light.power_w"),
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


def test_a_black_render_is_warned_about(tmp_path, capsys):
    """An exposure of 1e-46 is a valid positive scale that underflows every pixel to 0 in float32:
    the render is written, its sidecar counts no lit pixel and the command says so on stderr;
    the same scene at its own exposure lights nearly every pixel (the box's inside fills the frame)."""
    from workbench.cli import main

    dim = tmp_path / "dim.toml"
    assert "\nexposure = 1.0\n" in BASE
    dim.write_text(BASE.replace("\nexposure = 1.0\n", "\nexposure = 1e-46\n"))
    assert main(["render", str(dim), "--out", str(tmp_path / "dim.exr"), "--spp", "4", "--resolution", "40x30",
                 "--quiet"]) == 0
    assert "is black: no pixel received light" in capsys.readouterr().err
    assert json.loads((tmp_path / "dim.json").read_text())["lit_pixel_fraction"] == 0.0
    assert main(["render", "cornell_cd", "--out", str(tmp_path / "lit.exr"), "--spp", "4", "--resolution", "40x30",
                 "--quiet"]) == 0
    assert "is black" not in capsys.readouterr().err
    assert json.loads((tmp_path / "lit.json").read_text())["lit_pixel_fraction"] > 0.9


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

    from renderer.render import render
    from workbench.core.executor import DaskExecutor

    kwargs = dict(spp=192, resolution=(48, 36), progress=False)  # 4 passes of 48 spp (renderer.render.MIN_PASSES)
    render("cornell_cd", tmp_path / "local.exr", **kwargs)
    with DaskExecutor(workers=2) as executor:
        info = render("cornell_cd", tmp_path / "dask.exr", executor=executor, **kwargs)
    assert info["passes"] == 4
    for name in ("{}.exr", "{}.variance.exr"):  # the passes' spread too: the same passes, wherever they ran
        a = np.array(mi.Bitmap(str(tmp_path / name.format("local"))))
        b = np.array(mi.Bitmap(str(tmp_path / name.format("dask"))))
        assert np.allclose(a, b, rtol=1e-4, atol=1e-6 * float(np.abs(a).max()))


def test_box_size_rescales_the_measured_box(mitsuba_variant):
    """A 2x larger box: its walls are twice as far, and the camera check follows it."""
    import mitsuba as mi

    from renderer.mitsuba_scene import scene_dict

    text = BASE.replace('model = "cornell"', 'model = "cornell"\nsize = [1.112, 1.0976, 1.1184]')
    spec = parse_scene(text, source="big.toml", base_dir=None)
    d, _ = scene_dict(mi, spec, spp=1)
    bbox = mi.load_dict({"type": "scene", "floor": d["floor_white_0"]}).bbox()
    assert np.allclose([bbox.max.x, bbox.max.z], [1.1056, 1.1184], atol=1e-4)
