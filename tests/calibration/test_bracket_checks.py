"""Frames against their claimed exposure times (calibration/response/bracket.py, issue 45 item 1).

A bracket whose frames contradict their times is refused before any fit, naming the pair of
files, the claimed ratio and the measured one: the same image twice claimed 0.01 s and
0.04 s, a real bracket with its times reversed (developed and raw), a raw frame whose time is
wrong by more than the tolerance. Every synthetic bracket passes: this file's own (PNG and
DNG, 5 seeds each: 80 pairs) and the draft dataset's (`workbench synth`, 6 JPEG and 6 DNG
pairs), and the raw ratios measured there are the true ones to within the noise.
"""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from calibration.response import bracket as B
from calibration.response import calibrate as R
from tests.calibration.test_response import CURVES, EV, png_bracket, raw_bracket, srgb
from workbench.core.errors import UserInputError

# The raw ratio measured on synthetic brackets against the true one: shot noise only,
# measured within 0.10 % (test_response.py's DNGs, 5 seeds x 4 pairs) and 0.06 % (the draft
# dataset's, 6 pairs); 0.5 % bounds it with five times the room and is still 20 times tighter
# than the refusal tolerance B.RAW_RATIO_TOLERANCE.
RATIO_NOISE = 0.005
SEEDS = range(5)


def refused(files, match: str, times=None) -> UserInputError:
    reader = B.read_raw_bracket if str(files[0]).endswith(".dng") else B.read_bracket
    with pytest.raises(UserInputError, match=match) as error:
        reader(files, times)
    return error.value


# ---------------------------------------------------------------------------------------
# Refused: the frames contradict the times
# ---------------------------------------------------------------------------------------

def test_the_same_image_twice_is_refused(tmp_path):
    files, _ = png_bracket(tmp_path, srgb)
    error = refused([files[2], files[2]], "contradict their exposure times", [0.01, 0.04])
    assert "claimed x4.000, measured x1, the same image" in str(error) and str(error).count(files[2]) == 2
    raws, _ = raw_bracket(tmp_path)
    error = refused([raws[2], raws[2]], "contradict their exposure times", [0.01, 0.04])
    assert "claimed x4.000, measured x1.000 (the same exposure)" in str(error)


@pytest.mark.parametrize("kind", ["png", "dng"])
def test_reversed_times_are_refused_and_nothing_is_written(tmp_path, kind):
    files, times = png_bracket(tmp_path, srgb) if kind == "png" else raw_bracket(tmp_path)
    out = tmp_path / "out" / "response.json"
    with pytest.raises(UserInputError, match="contradict their exposure times") as error:
        R.calibrate_response(files, out, times_s=times[::-1])
    assert not out.exists()   # before: a raw bracket's slope -1 wrote 0 ** -1 = Infinity into it
    # The pair named is the first pair in claimed time: the last file (shortest claimed) and the one before.
    assert f"{files[-1]} ({times[0]:g} s) and {files[-2]} ({times[1]:g} s)" in str(error.value)
    assert "claimed x2.000" in str(error.value)
    if kind == "dng":
        assert "measured x0.500" in str(error.value)   # the true ratio, inverted: the median is exact to 0.1 %
    else:
        assert "measured not above x1" in str(error.value)


def test_a_raw_time_wrong_beyond_the_tolerance_is_refused(tmp_path):
    """One frame's time 30 % long: its pair is off the bracket's ratios by 30 % (tolerance 10 %);
    5 % long (within a camera's nominal-time rounding) passes."""
    files, times = raw_bracket(tmp_path)
    wrong = times.copy()
    wrong[-1] *= 1.3
    error = refused(files, "contradict their exposure times", wrong)
    assert f"{files[-2]} ({times[-2]:g} s) and {files[-1]}" in str(error) and "claimed x2.600" in str(error)
    measured = float(re.search(r"measured x([0-9.]+)", str(error)).group(1))
    assert measured == pytest.approx(2.0, rel=RATIO_NOISE)   # the true ratio
    close = times.copy()
    close[-1] *= 1.05
    B.read_raw_bracket(files, close)


def test_a_non_linear_raw_is_not_taken_for_wrong_times(tmp_path):
    """Raw values ~ (E t)^0.8: every pair measures x2^0.8 = x1.741, one common power, which the
    linearity check reports (test_response.py) rather than this check refusing it."""
    files, times = raw_bracket(tmp_path, power=0.8)
    rows = B.raw_pair_ratios(B.read_raw_bracket(files))
    assert [m for _, _, m, _ in rows] == pytest.approx([2.0**0.8] * len(EV[1:]), rel=RATIO_NOISE)


def test_command_line_refusal_is_one_line(tmp_path, capsys):
    from workbench.cli import main

    files, _ = png_bracket(tmp_path, srgb)
    out = tmp_path / "response.json"
    code = main(["calibrate", "response", files[2], files[2], "--times", "0.01,0.04", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err
    assert "claimed x4.000" in err and not out.exists()


def test_a_raw_record_never_holds_a_power_law_without_positive_slope():
    from calibration.response.record import raw_record

    with pytest.raises(UserInputError, match="do not grow with the exposure"):
        raw_record([], {"linear": False, "slope": -0.998, "times_s": [0.02, 0.01]}, {})


# ---------------------------------------------------------------------------------------
# Accepted: synthetic brackets (false alarms: none of 80 + 12 pairs)
# ---------------------------------------------------------------------------------------

def test_synthetic_brackets_pass_and_raw_ratios_are_the_true_ones(tmp_path):
    pairs = 0
    for seed in SEEDS:
        for name, curve in sorted(CURVES.items()):
            folder = tmp_path / f"{name}{seed}"
            folder.mkdir()
            files, times = png_bracket(folder, curve, seed=seed)
            B.read_bracket(files, times)
            pairs += len(files) - 1
        for power in (1.0, 0.8):
            folder = tmp_path / f"raw{power}-{seed}"
            folder.mkdir()
            files, times = raw_bracket(folder, power=power, seed=seed)
            rows = B.raw_pair_ratios(B.read_raw_bracket(files))
            assert [m for _, _, m, _ in rows] == pytest.approx([c**power for _, c, _, _ in rows], rel=RATIO_NOISE)
            pairs += len(rows)
    assert pairs == 80


@pytest.fixture(scope="module")
def brackets(tmp_path_factory):
    from tests.conftest import synthetic_dataset

    out = synthetic_dataset(tmp_path_factory, 0)  # the suite's shared seed-0 dataset (tests/conftest.py)
    seconds = json.loads((out / "truth.json").read_text())["exposure_time_s"]
    names = sorted((p.name for p in (out / "brackets").iterdir()), key=lambda n: seconds[n])  # shortest first
    return out / "brackets", [n for n in names if n.endswith(".jpg")], [n for n in names if n.endswith(".dng")]


@pytest.mark.slow
def test_draft_dataset_brackets_pass_and_their_disorder_is_refused(brackets):
    folder, jpegs, dngs = brackets
    jpeg_files, dng_files = [str(folder / n) for n in jpegs], [str(folder / n) for n in dngs]
    B.read_bracket(jpeg_files)
    raw = B.read_raw_bracket(dng_files)
    rows = B.raw_pair_ratios(raw)
    assert len(rows) == len(dngs) - 1
    assert [m for _, _, m, _ in rows] == pytest.approx([c for _, c, _, _ in rows], rel=RATIO_NOISE)
    reversed_times = list(raw.times_s[::-1])
    refused(jpeg_files, "measured not above x1", reversed_times)
    refused(dng_files, "contradict their exposure times", reversed_times)
    middle = len(jpegs) // 2
    refused([jpeg_files[middle]] * 2, "the same image", [0.01, 0.04])
    assert np.all(np.diff(raw.times_s) > 0)
