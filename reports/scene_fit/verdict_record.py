"""The scene fit's verdict as a typed record: its one writer and one reader of scene_fit.json's ``verdict``.

reports.scene_fit.verdict decides it; the fit command, verify, the report page and a run's
index read it back through :meth:`Verdict.from_json`, so a key is named in one place. The
record holds numbers only (no numpy), and its JSON is what scene_fit.json has always held.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

from workbench.core.errors import UserInputError


class Outcome(StrEnum):
    """The four verdicts (reports.scene_fit.verdict's module docstring says when each is given)."""

    CONSISTENT = "consistent"
    MODEL = "model"
    CAMERA = "camera"
    UNEXPLAINED = "unexplained"


@dataclass(frozen=True)
class ChiSquare:
    """A test statistic with its degrees of freedom and p-value (chi-square)."""

    statistic: float
    dof: int
    p_value: float

    def to_json(self) -> dict[str, float]:
        return {"statistic": self.statistic, "dof": self.dof, "p_value": self.p_value}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> ChiSquare:
        return cls(float(data["statistic"]), int(data["dof"]), float(data["p_value"]))


@dataclass(frozen=True)
class Residuals:
    """The absolute residuals' median and 95th percentile (pixels), and how many there are."""

    median: float
    p95: float
    count: int

    def to_json(self) -> dict[str, float]:
        return {"median": self.median, "p95": self.p95, "count": self.count}

    @classmethod
    def from_json(cls, data: dict[str, Any] | None) -> Residuals | None:
        if data is None:
            return None
        return cls(_number(data.get("median")), _number(data.get("p95")), int(data.get("count", 0)))


@dataclass(frozen=True)
class MovedParameter:
    """A fitted component that moved by more than the verdict's threshold (in its standard deviations)."""

    name: str
    component: str
    nominal: float
    fitted: float
    std: float
    sigmas: float

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "component": self.component, "nominal": self.nominal, "fitted": self.fitted,
                "std": self.std, "sigmas": self.sigmas}


@dataclass(frozen=True)
class CameraFit:
    """The scene file's residuals explained by the camera alone (reports.scene_fit.verdict.camera_only_fit)."""

    median_px: float
    statistic: float
    dof: int
    p_value: float
    moved_std: dict[str, float]

    def to_json(self) -> dict[str, Any]:
        return {"median_px": self.median_px, "statistic": self.statistic, "dof": self.dof, "p_value": self.p_value,
                "moved_std": dict(self.moved_std)}

    @classmethod
    def from_json(cls, data: dict[str, Any] | None) -> CameraFit | None:
        if data is None:
            return None
        return cls(float(data["median_px"]), float(data["statistic"]), int(data["dof"]), float(data["p_value"]),
                   {str(k): float(v) for k, v in data["moved_std"].items()})


@dataclass(frozen=True)
class Verdict:
    """scene_fit.json's ``verdict``: the outcome, why, the test's numbers and what moved.

    ``test`` keeps the test's description as written (method, alpha, noise per group, counts
    and the three statistics); ``noise_only`` and ``noise_and_camera`` are its two Wald tests.
    """

    outcome: Outcome
    why: str
    test: dict[str, Any]
    moved_sigmas: float
    parameters: tuple[MovedParameter, ...]
    camera_fit: CameraFit | None
    residuals_before_px: Residuals
    residuals_after_px: Residuals
    rim_residuals_before_px: Residuals | None = None
    rim_residuals_after_px: Residuals | None = None
    largest_residuals: tuple[dict[str, Any], ...] | None = None

    @property
    def noise_only(self) -> ChiSquare:
        return ChiSquare.from_json(self.test["noise_only"])

    @property
    def noise_and_camera(self) -> ChiSquare | None:
        camera = self.test.get("noise_and_camera")
        return None if camera is None else ChiSquare.from_json(camera)

    def to_json(self) -> dict[str, Any]:
        """The record as scene_fit.json holds it."""
        out: dict[str, Any] = {
            "verdict": self.outcome.value, "why": self.why, "test": self.test, "moved_sigmas": self.moved_sigmas,
            "parameters": [p.to_json() for p in self.parameters],
            "camera_fit": None if self.camera_fit is None else self.camera_fit.to_json(),
            "residuals_before_px": self.residuals_before_px.to_json(),
            "residuals_after_px": self.residuals_after_px.to_json(),
            "rim_residuals_before_px": _json_or_none(self.rim_residuals_before_px),
            "rim_residuals_after_px": _json_or_none(self.rim_residuals_after_px),
        }
        if self.largest_residuals is not None:
            out["largest_residuals"] = list(self.largest_residuals)
        return out

    @classmethod
    def from_json(cls, data: Any, source: Path | str | None = None) -> Verdict:
        """The verdict read back from scene_fit.json (``source``, named in errors).

        Raises
        ------
        UserInputError
            Where the record is not a verdict: not a table, an unknown outcome, a missing field.
        """
        if not isinstance(data, dict):
            raise UserInputError("the scene fit's verdict is not a table", file=source, field="verdict",
                                 expected="a JSON object", got=type(data).__name__)
        try:
            outcome = Outcome(data["verdict"])
            return cls(outcome, str(data["why"]), dict(data["test"]), float(data.get("moved_sigmas", math.nan)),
                       tuple(MovedParameter(**p) for p in data.get("parameters") or []),
                       CameraFit.from_json(data.get("camera_fit")),
                       _residuals(data, "residuals_before_px"), _residuals(data, "residuals_after_px"),
                       Residuals.from_json(data.get("rim_residuals_before_px")),
                       Residuals.from_json(data.get("rim_residuals_after_px")),
                       None if data.get("largest_residuals") is None else tuple(data["largest_residuals"]))
        except ValueError as error:
            raise UserInputError("the scene fit's verdict is not one of the four", file=source, field="verdict.verdict",
                                 expected=", ".join(o.value for o in Outcome), got=data.get("verdict")) from error
        except (KeyError, TypeError) as error:
            raise UserInputError("the scene fit's verdict lacks a field or has one of the wrong kind", file=source,
                                 field=f"verdict.{error.args[0] if error.args else '?'}",
                                 expected="a verdict written by `workbench fit`") from error


def _residuals(data: dict[str, Any], key: str) -> Residuals:
    found = Residuals.from_json(data[key])
    if found is None:
        raise KeyError(key)
    return found


def _number(value: Any) -> float:
    return math.nan if value is None else float(value)


def _json_or_none(residuals: Residuals | None) -> dict[str, float] | None:
    return None if residuals is None else residuals.to_json()
