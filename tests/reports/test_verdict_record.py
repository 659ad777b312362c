"""The scene fit's verdict as a typed record (reports.scene_fit.verdict_record): one writer, one reader.

A record written by ``to_json`` reads back equal, survives a JSON round trip to the same text,
and a damaged verdict is refused with the file and the field named.
"""

from __future__ import annotations

import json

import pytest

from reports.scene_fit.verdict_record import CameraFit, ChiSquare, MovedParameter, Outcome, Residuals, Verdict
from workbench.core.errors import UserInputError


def _verdict(outcome: Outcome) -> Verdict:
    test = {"method": "Wald", "alpha": 1e-3, "noise_px": {"circles": 0.3}, "edges": 40, "rim_points": 12,
            "noise_only": ChiSquare(25.0, 1, 5.7e-7).to_json(), "noise_and_camera": None,
            "likelihood_ratio": ChiSquare(20.0, 1, 7.7e-6).to_json()}
    moved = (MovedParameter("cd[0].structure.period", "cd[0].structure.period", 1.6, 1.68, 0.004, 20.0),)
    return Verdict(outcome, "why", test, 3.0, moved if outcome is Outcome.MODEL else (),
                   CameraFit(0.9, 3.2, 6, 0.78, {"fx": 1.2, "cx": 0.4}), Residuals(1.2, 3.0, 40), Residuals(0.2, 0.6, 40),
                   Residuals(0.3, 0.8, 12), Residuals(0.1, 0.3, 12),
                   ({"photo": "view0.dng", "residual_px": 2.0},) if outcome is Outcome.UNEXPLAINED else None)


@pytest.mark.parametrize("outcome", list(Outcome))
def test_a_verdict_reads_back_as_written(outcome):
    written = _verdict(outcome).to_json()
    text = json.dumps(written, indent=2)
    read = Verdict.from_json(json.loads(text))
    assert read == _verdict(outcome)
    assert json.dumps(read.to_json(), indent=2) == text
    assert read.noise_only.p_value == pytest.approx(5.7e-7) and read.noise_and_camera is None
    assert ("largest_residuals" in written) == (outcome is Outcome.UNEXPLAINED)  # as scene_fit.json has always held it


def test_the_four_outcomes_are_the_strings_the_files_hold():
    assert [o.value for o in Outcome] == ["consistent", "model", "camera", "unexplained"]
    assert Outcome.MODEL == "model"


@pytest.mark.parametrize(("change", "field"), [
    ({"verdict": "maybe"}, "verdict.verdict"),
    ({"residuals_after_px": None}, "verdict.residuals_after_px"),
])
def test_a_damaged_verdict_is_refused_naming_the_file_and_field(change, field):
    data = _verdict(Outcome.MODEL).to_json() | change
    with pytest.raises(UserInputError) as caught:
        Verdict.from_json(data, "RUN/fit/scene_fit.json")
    assert caught.value.field == field and "scene_fit.json" in str(caught.value)
    with pytest.raises(UserInputError):
        Verdict.from_json(["not", "a", "table"], "x.json")
