"""calibration.response.calibrate: the camera response from exposure brackets, the raw linearity check,
and every bad input the command must refuse.

Brackets are made here: a smooth irradiance map with a wide range, times 1 EV apart, a known
monotone curve, shot noise and 8-bit quantisation (the pixel model of Debevec & Malik 1997,
Z = f(E t)); one module-scoped draft dataset (``workbench synth``, about a minute) checks
the real camera JPEGs against the truth the dataset hides from the calibration.
"""

from __future__ import annotations

import json
import math
from fractions import Fraction

import cv2
import numpy as np
import pytest
from PIL import Image, TiffImagePlugin

from calibration.response import bracket as response_bracket
from calibration.response import calibrate as R
from renderer.response import ResponseCurve
from workbench.core.errors import UserInputError

# The issue's bar: response curve RMS < 1 % (of the value range) over values 0.05-0.95.
RESPONSE_RMS_TOLERANCE = 0.01
# A raw bracket is linear: the slope of ln value against ln time is 1 to within shot noise
# (thousands of pixels) and the 14-bit quantisation; 0.01 leaves room for both and still
# tells a 0.8 power from linear by twenty times.
# Noise (issue 23), measured over realisations: the slope is one fit pooled over every usable
# pixel (12,000-15,000 here, 307,000 in the draft dataset), not a mean of a dark patch, so it
# has none of test_decode.py::test_raw_bracket_is_linear's dark-patch problem. raw_bracket's
# shot noise and quantisation over 2000 seeds: slope - 1 = 2.2e-4 +- 1.8e-4 (the bias: ln of
# noisy values near the usable floor, 0.02 of the range), max 8.6e-4; power 0.8 over 1000
# seeds: 3.8e-4 +- 1.7e-4. The bound is 55 standard deviations from the mean (Gaussian tail
# < 1e-300). The draft dataset's DNGs (one render re-exposed: its Monte Carlo noise is common
# to the frames and cancels in each pixel's slope) with shot, read (3 e-) and quantisation
# noise redrawn 100 times from the rate each pixel's 7 frames give: 1.6e-4 +- 3e-5, max
# 2.4e-4 (the dataset itself 1.05e-4): about 300 standard deviations. False alarms per run: < 1e-100 for
# the three uses. Still caught: a raw response of power 0.985 or 1.01 (slope - 1 = -0.0148,
# +0.0102); power 0.99 passes (-0.0098).
RAW_SLOPE_TOLERANCE = 0.01
# OpenCV's curves against the parametric one, in ln(irradiance) over the mid-range after
# their unknown scale is removed: measured 0.01-0.05 on this file's clean brackets (both
# OpenCV methods are noisier in the dark, where they have one unknown per code value).
OPENCV_LOG_RMS_TOLERANCE = 0.1
EV = np.arange(-2, 3)
FULL_WELL_E = 16000.0   # electrons at normalised irradiance 1 (the synthetic sensor's 14-bit range)


def srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB encoding (IEC 61966-2-1): a linear toe, then a 1/2.4 power."""
    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def shoulder(x: np.ndarray) -> np.ndarray:
    """A gamma-2 curve rolled off towards the top, u (1 + a) / (u + a) with u = sqrt(x)."""
    u = np.sqrt(np.clip(x, 0.0, 1.0))
    return u * 1.5 / (u + 0.5)


CURVES = {"srgb": srgb, "shoulder": shoulder}


def curve_truth(curve) -> list[list[float]]:
    x = np.linspace(0.0, 1.0, 2049) ** 2
    return [[float(a), float(b)] for a, b in zip(x, curve(x), strict=True)]


def irradiance_map(height: int = 120, width: int = 160) -> np.ndarray:
    """Smooth ramps over 8 stops (plus a gentle tilt) in three horizontal bands of different
    colours, so that each channel reaches saturation somewhere before the others do: at the
    middle exposure the brightest channel runs from about 0.004 to 1.2."""
    u = np.linspace(0.0, 1.0, width)[None, :, None] + 0.1 * np.linspace(0.0, 1.0, height)[:, None, None]
    band = np.minimum(3 * np.arange(height) // height, 2)
    colours = np.array([[1.0, 0.5, 0.3], [0.3, 1.0, 0.5], [0.5, 0.3, 1.0]])[band][:, None, :]
    return np.exp(math.log(0.004) + math.log(300.0) * u / 1.1) * colours


def bracket_codes(curve, rng: np.random.Generator, bits: int = 8, grey: bool = False) -> tuple[list[np.ndarray], np.ndarray]:
    """Codes of the bracket (one image per EV) and its times: shot noise on E t, the curve,
    quantisation to ``bits``."""
    irradiance = irradiance_map()
    if grey:
        irradiance = irradiance[:, :, 1:2]
    times = 0.01 * 2.0**EV
    top = 2**bits - 1
    images = []
    for t in times:
        x = irradiance * t / 0.01
        x = x + rng.standard_normal(x.shape) * np.sqrt(x / FULL_WELL_E)
        images.append(np.rint(top * curve(x)).astype(np.uint8 if bits == 8 else np.uint16))
    return images, times


def write_png(path, codes: np.ndarray) -> str:
    image = codes if codes.shape[2] == 1 else codes[:, :, ::-1]
    assert cv2.imwrite(str(path), image)
    return str(path)


def write_jpeg_with_time(path, codes: np.ndarray, seconds: float | None) -> str:
    exif = Image.Exif()
    if seconds is not None:
        t = Fraction(seconds).limit_denominator(1_000_000)
        exif.get_ifd(0x8769)[0x829A] = TiffImagePlugin.IFDRational(t.numerator, t.denominator)
    Image.fromarray(codes, "RGB").save(path, format="JPEG", quality=95, subsampling=0, exif=exif)
    return str(path)


def png_bracket(tmp_path, curve, seed: int = 0, **kwargs) -> tuple[list[str], np.ndarray]:
    images, times = bracket_codes(curve, np.random.default_rng(seed), **kwargs)
    return [write_png(tmp_path / f"ev{ev:+d}.png", image) for ev, image in zip(EV, images, strict=True)], times


def is_monotone(points) -> bool:
    x, y = np.asarray(points).T
    return bool(np.all(np.diff(x) > 0) and np.all(np.diff(y) > 0))


# ---------------------------------------------------------------------------------------
# Recovering a known curve
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", sorted(CURVES))
def test_parametric_recovers_a_known_curve(tmp_path, name):
    files, times = png_bracket(tmp_path, CURVES[name])
    out = tmp_path / "response.json"
    result = R.calibrate_response(files, out, times_s=times)
    assert json.loads(out.read_text()) == json.loads(json.dumps(result))
    assert result["method"] == "parametric" and result["linear"] is False
    assert R.response_rms(result["points"], curve_truth(CURVES[name])) < RESPONSE_RMS_TOLERANCE
    for channel, points in result["channels"].items():  # each channel went through the same curve
        assert R.response_rms(points, curve_truth(CURVES[name])) < RESPONSE_RMS_TOLERANCE, channel
    assert is_monotone(result["points"]) and result["points"][0] == [0.0, 0.0] and result["points"][-1] == [1.0, 1.0]
    assert ResponseCurve.from_spec({"points": result["points"]}).kind == "points"  # what the renderer and decode read
    assert result["times_s"] == pytest.approx(list(times)) and result["files"] == files


def test_opencv_methods_agree_in_the_log_domain_and_mask_unseen_values(tmp_path):
    """Debevec and Robertson are reported beside the parametric curve; values that never
    occur (the codes below the shoulder curve's darkest value) are left out, never NaN."""
    files, times = png_bracket(tmp_path, shoulder)
    result = R.calibrate_response(files, tmp_path / "r.json", times_s=times)
    codes = np.stack([cv2.imread(f, cv2.IMREAD_UNCHANGED) for f in files])
    unseen = 256 - len(np.unique(codes[..., 1]))
    assert unseen > 0  # the test needs values that never occur
    for method in ("debevec", "robertson"):
        other = result["others"][method]
        for channel, entry in other["channels"].items():
            difference = entry["log_difference"]
            assert difference["rms"] < OPENCV_LOG_RMS_TOLERANCE, (method, channel, difference)
            assert all(math.isfinite(v) for pair in entry["points"] for v in pair)
        assert len(other["channels"]["G"]["points"]) <= 256 - unseen
    assert "NaN" not in (tmp_path / "r.json").read_text()


def test_sixteen_bit_grey_bracket(tmp_path):
    files, times = png_bracket(tmp_path, shoulder, bits=16, grey=True)
    result = R.calibrate_response(files, times_s=times)
    assert list(result["channels"]) == ["grey"] and result["settings"]["bits"] == 16
    assert R.response_rms(result["points"], curve_truth(shoulder)) < RESPONSE_RMS_TOLERANCE


def test_exposure_times_from_exif(tmp_path):
    images, times = bracket_codes(srgb, np.random.default_rng(1))
    files = [write_jpeg_with_time(tmp_path / f"ev{ev:+d}.jpg", image, t) for ev, image, t in zip(EV, images, times, strict=True)]
    result = R.calibrate_response(files)
    assert result["times_s"] == pytest.approx(list(times), rel=1e-6)
    assert R.response_rms(result["points"], curve_truth(srgb)) < RESPONSE_RMS_TOLERANCE


def test_large_images_are_read_at_a_stride(tmp_path, monkeypatch):
    files, times = png_bracket(tmp_path, srgb)
    monkeypatch.setattr(response_bracket, "MAX_PIXELS", 120 * 160 // 4)
    bracket = R.read_bracket(files, times)
    assert bracket.stride == 2 and bracket.codes.shape[1:3] == (60, 80)


def test_a_bracket_that_never_nears_saturation_is_warned_about(tmp_path):
    """The two shortest exposures alone stay far below saturation: the curve's top, and with
    it the irradiance scale, is extrapolated, and response.json says so."""
    files, times = png_bracket(tmp_path, srgb)
    result = R.calibrate_response(files[:2], times_s=times[:2])
    assert result["value_range"][1] < 0.9 and any("add a longer exposure" in w for w in result["warnings"])
    assert not R.calibrate_response(files, times_s=times)["warnings"]


def test_method_registry_and_dispatcher(tmp_path):
    files, times = png_bracket(tmp_path, srgb)
    bracket = R.read_bracket(files, times)
    assert set(R.RESPONSE_METHODS) == {"debevec", "robertson", "parametric"}
    curves = R.fit_response(bracket, "parametric", knots=4)
    assert curves.channels == ("R", "G", "B", "all") and curves.log_irradiance.shape == (256, 4)
    with pytest.raises(UserInputError, match="unknown response method"):
        R.fit_response(bracket, "mitsunaga")


def test_knot_study_trades_accuracy_for_knots(tmp_path):
    """The study hook: one knot pair (a slope that varies linearly) cannot follow the sRGB
    toe-and-power shape as well as six knots do."""
    files, times = png_bracket(tmp_path, srgb)
    rows = R.parametric_knot_study(R.read_bracket(files, times), curve_truth(srgb), knot_counts=(2, 6))
    assert [row["knots"] for row in rows] == [2, 6] and all(row["seconds"] > 0 for row in rows)
    assert rows[1]["rms"] < rows[0]["rms"] and rows[1]["rms"] < RESPONSE_RMS_TOLERANCE


def test_slope_model_is_a_gamma_curve_for_a_constant_slope():
    """One constant slope s is the power law g(y) = y^s: the closed-form integral checked."""
    model = R.SlopeResponse(np.array([0.1, 0.5, 0.9]), np.array([2.2, 2.2, 2.2]))
    y = np.array([1e-3, 0.05, 0.3, 0.7, 0.95, 1.0])
    assert model.log_irradiance(y) == pytest.approx(2.2 * np.log(y), abs=1e-12)
    varying = R.SlopeResponse(np.array([0.2, 0.6]), np.array([1.0, 3.0]))
    grid = np.linspace(0.05, 1.0, 2001)
    slope = np.interp(grid, [0.2, 0.6], [1.0, 3.0])  # constant beyond the knots
    from_y0 = np.r_[0.0, np.cumsum(np.diff(np.log(grid)) * 0.5 * (slope[1:] + slope[:-1]))]  # trapezoid in ln y
    assert varying.log_irradiance(grid) == pytest.approx(from_y0 - from_y0[-1], abs=1e-6)


# ---------------------------------------------------------------------------------------
# Raw brackets: linearity
# ---------------------------------------------------------------------------------------

def raw_bracket(tmp_path, power: float = 1.0, seed: int = 3) -> tuple[list[str], np.ndarray]:
    """DNGs of the irradiance map's green channel through a 14-bit sensor, optionally raised
    to ``power`` (a non-linear raw)."""
    from datasets_synthetic.dng import DngMetadata, write_dng

    rng = np.random.default_rng(seed)
    irradiance = irradiance_map(128, 128)[:, :, 1]
    times = 0.01 * 2.0**EV
    black, white = 512, 16383
    files = []
    for ev, t in zip(EV, times, strict=True):
        x = np.clip(irradiance * t / 0.01, 0, None)
        x = x + rng.standard_normal(x.shape) * np.sqrt(x / FULL_WELL_E)
        raw = np.clip(np.rint(black + (white - black) * np.clip(x, 0, None) ** power), 0, white).astype(np.uint16)
        files.append(str(write_dng(tmp_path / f"ev{ev:+d}.dng", raw, DngMetadata(exposure_time_s=float(t)))))
    return files, times


def test_raw_bracket_is_linear(tmp_path):
    files, times = raw_bracket(tmp_path)
    result = R.calibrate_response(files, tmp_path / "response.json")
    assert result["method"] == "raw-linearity" and result["linear"] is True
    assert abs(result["linearity"]["slope_deviation"]) < RAW_SLOPE_TOLERANCE
    assert result["times_s"] == pytest.approx(list(times), rel=1e-6)  # LibRaw's shutter time
    assert result["points"][0] == [0.0, 0.0] and result["points"][-1] == [1.0, 1.0]
    assert json.loads((tmp_path / "response.json").read_text())["linear"] is True


def test_truncated_raw_names_the_file(tmp_path):
    files, _ = raw_bracket(tmp_path)
    data = open(files[2], "rb").read()
    open(files[2], "wb").write(data[: len(data) // 3])
    error = refused(tmp_path, files, "cannot read the raw file")
    assert error.file == files[2]


def test_non_linear_raw_is_reported(tmp_path):
    files, _ = raw_bracket(tmp_path, power=0.8)
    result = R.calibrate_response(files)
    assert result["linear"] is False
    assert result["linearity"]["slope"] == pytest.approx(0.8, abs=RAW_SLOPE_TOLERANCE)
    x, y = np.asarray(result["points"]).T
    assert y[128] == pytest.approx(x[128] ** result["linearity"]["slope"])


# ---------------------------------------------------------------------------------------
# Bad input: a clear error that names the file, nothing written
# ---------------------------------------------------------------------------------------

def refused(tmp_path, files, match, **kwargs) -> UserInputError:
    out = tmp_path / "out" / "response.json"
    with pytest.raises(UserInputError, match=match) as error:
        R.calibrate_response(files, out, **kwargs)
    assert not out.exists()
    return error.value


def test_jpeg_without_exposure_time_names_the_file(tmp_path):
    images, times = bracket_codes(srgb, np.random.default_rng(1))
    files = [write_jpeg_with_time(tmp_path / f"ev{ev:+d}.jpg", image, t if ev != 1 else None)
             for ev, image, t in zip(EV, images, times, strict=True)]
    error = refused(tmp_path, files, "no exposure time")
    assert error.file == files[3] and "--times" in str(error)
    assert R.calibrate_response(files, times_s=times)["times_s"] == pytest.approx(list(times))  # --times rescues it


def test_fewer_than_two_images(tmp_path):
    files, _ = png_bracket(tmp_path, srgb)
    refused(tmp_path, files[:1], "needs an exposure bracket", times_s=[0.01])


def test_times_count_mismatch(tmp_path):
    files, times = png_bracket(tmp_path, srgb)
    error = refused(tmp_path, files, "one exposure time per image", times_s=times[:3])
    assert error.field == "--times"


def test_images_of_different_sizes(tmp_path):
    files, times = png_bracket(tmp_path, srgb)
    write_png(tmp_path / "ev+1.png", np.zeros((60, 80, 3), np.uint8) + 100)
    error = refused(tmp_path, files, "differs from the bracket's first image", times_s=times)
    assert error.file == files[3] and "160 x 120" in str(error)


@pytest.mark.parametrize(("value", "word"), [(255, "saturated"), (0, "black")])
def test_all_saturated_or_all_black_image(tmp_path, value, word):
    files, times = png_bracket(tmp_path, srgb)
    write_png(tmp_path / "ev-1.png", np.full((120, 160, 3), value, np.uint8))
    error = refused(tmp_path, files, f"{word} everywhere", times_s=times)
    assert error.file == files[1]


def test_exposures_that_never_overlap(tmp_path):
    """Each image has usable values, but never at the same pixel: nothing ties them together."""
    dark, bright = np.zeros((120, 160, 3), np.uint8), np.full((120, 160, 3), 255, np.uint8)
    dark[:, :40], bright[:, 120:] = 128, 128
    files = [write_png(tmp_path / "a.png", dark), write_png(tmp_path / "b.png", bright)]
    error = refused(tmp_path, files, "no pixel keeps a usable value in two exposures", times_s=[0.01, 0.02])
    assert error.got == files


def test_other_bad_brackets(tmp_path):
    files, times = png_bracket(tmp_path, srgb)
    refused(tmp_path, files, "same exposure time", times_s=[0.01] * len(files))
    refused(tmp_path, files, "positive seconds", times_s=[0.01, -1, 0.02, 0.04, 0.08])
    (tmp_path / "broken.png").write_bytes(open(files[0], "rb").read()[:200])
    refused(tmp_path, [files[0], str(tmp_path / "broken.png")], "cannot read", times_s=times[:2])
    refused(tmp_path, [files[0], str(tmp_path / "missing.png")], "no such file", times_s=times[:2])
    (tmp_path / "a.dng").write_bytes(b"")
    refused(tmp_path, [files[0], str(tmp_path / "a.dng")], "mixes raw and developed", times_s=times[:2])
    refused(tmp_path, files, "unknown response method", times_s=times, compare=("mitsunaga",))


# ---------------------------------------------------------------------------------------
# The draft synthetic dataset: camera JPEGs against the hidden truth
# ---------------------------------------------------------------------------------------

def log_curve_of(points, inverse: bool = False) -> np.ndarray:
    """ln(normalised irradiance) at R.CURVE_VALUES of a curve given as [irradiance, value]
    pairs: read at its own values, or (``inverse``, for a truth table sampled in irradiance)
    by inverting its monotone cubic."""
    x, y = np.asarray(points, dtype=float).T
    if inverse:
        from scipy.interpolate import PchipInterpolator

        grid = np.linspace(0.0, 1.0, 8193)
        x, y = grid, PchipInterpolator(x, y)(grid)
        with np.errstate(divide="ignore"):
            return np.log(np.interp(R.CURVE_VALUES, y, x))
    out = np.full(len(R.CURVE_VALUES), np.nan)
    index = np.rint(y * 255).astype(int)
    out[index[x > 0]] = np.log(x[x > 0])
    return out


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from tests.conftest import synthetic_dataset

    out = synthetic_dataset(tmp_path_factory, 0)  # the suite's shared seed-0 dataset (tests/conftest.py)
    return out, json.loads((out / "truth.json").read_text())


@pytest.mark.slow
def test_draft_dataset_jpeg_bracket_meets_the_issue_bar(dataset, tmp_path):
    out, truth = dataset
    jpegs = sorted(str(p) for p in (out / "brackets").glob("*.jpg"))
    result = R.calibrate_response(jpegs, tmp_path / "response.json")
    rms = R.response_rms(result["points"], truth["response"]["points"])
    assert rms < RESPONSE_RMS_TOLERANCE, rms
    names = [p.rsplit("/", 1)[-1] for p in jpegs]
    assert result["times_s"] == pytest.approx([truth["exposure_time_s"][n] for n in names], rel=1e-6)
    # In the log domain too (shape only: each curve's offset removed), the workbench's curve is
    # nearer the truth than OpenCV's on any channel (measured 0.013-0.017 against 0.03-0.18).
    truth_log = log_curve_of(truth["response"]["points"], inverse=True)
    ours = R.log_domain_difference(log_curve_of(result["points"]), truth_log)["rms"]
    for method in ("debevec", "robertson"):
        for channel, entry in result["others"][method]["channels"].items():
            assert ours < R.log_domain_difference(log_curve_of(entry["points"]), truth_log)["rms"], (method, channel)


@pytest.mark.slow
def test_draft_dataset_raw_bracket_is_linear(dataset):
    out, _ = dataset
    result = R.calibrate_response(sorted((out / "brackets").glob("*.dng")))
    assert result["linear"] is True and abs(result["linearity"]["slope_deviation"]) < RAW_SLOPE_TOLERANCE
