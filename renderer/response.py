"""Camera response curves: normalized irradiance in [0, 1] to normalized output value.

Renders are linear camera RGB; a response curve is applied only to compare with non-raw
photographs (JPEGs). Three forms, one short function each:
* ``linear``: f(x) = x (raw files);
* ``gamma``: f(x) = x^(1/gamma) (a pure power law, the usual first model, e.g. [Debevec 1997]
  fit responses of this family well for many cameras);
* ``points``: a monotone curve through measured samples, interpolated with a monotone
  cubic (scipy PchipInterpolator), e.g. one recovered from exposure brackets.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from workbench.core.errors import UserInputError

RESPONSE_KINDS = ("linear", "gamma", "points")


@dataclass(frozen=True)
class ResponseCurve:
    kind: str = "linear"
    gamma: float = 1.0
    points: tuple[tuple[float, float], ...] = ()

    @classmethod
    def from_spec(cls, spec, where: str = "camera.response") -> "ResponseCurve":
        if spec in (None, "linear"):
            return cls()
        if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in ("gamma", "points"):
            expected = '"linear", { gamma = G } or { points = [[x, y], ...] }'
            raise UserInputError("unknown response curve", field=where, expected=expected, got=spec)
        if "gamma" in spec:
            g = spec["gamma"]
            if isinstance(g, bool) or not isinstance(g, (int, float)) or not g > 0:
                raise UserInputError("must be a positive number", field=f"{where}.gamma", got=g)
            return cls("gamma", float(g))
        try:
            pts = np.asarray(spec["points"], dtype=float)
        except (TypeError, ValueError):  # ragged pairs, or entries that are not numbers
            pts = np.empty(0)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
            raise UserInputError("must list at least two [x, y] pairs of finite numbers", field=f"{where}.points",
                                 got=spec["points"])
        if np.any(np.diff(pts[:, 0]) <= 0) or np.any(np.diff(pts[:, 1]) < 0):
            raise UserInputError(
                "the curve must increase (x strictly, y monotonically)", field=f"{where}.points", got=spec["points"]
            )
        if pts[0, 0] > 0 or pts[-1, 0] < 1:
            raise UserInputError("the samples must span x from 0 to 1", field=f"{where}.points", got=spec["points"])
        return cls("points", 1.0, tuple(map(tuple, pts)))

    def apply(self, x: np.ndarray) -> np.ndarray:
        x = np.clip(np.asarray(x, dtype=float), 0.0, 1.0)
        if self.kind == "linear":
            return x
        if self.kind == "gamma":
            return x ** (1.0 / self.gamma)
        pts = np.asarray(self.points)
        return PchipInterpolator(pts[:, 0], pts[:, 1])(x)

    def invert(self, y: np.ndarray) -> np.ndarray:
        y = np.clip(np.asarray(y, dtype=float), 0.0, 1.0)
        if self.kind == "linear":
            return y
        if self.kind == "gamma":
            return y**self.gamma
        grid = np.linspace(0.0, 1.0, 4097)
        return np.interp(y, self.apply(grid), grid)

    def to_json(self) -> dict:
        return {"kind": self.kind, "gamma": self.gamma, "points": [list(p) for p in self.points]}
