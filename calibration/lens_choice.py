"""``calibrate intrinsics --model auto``: the lens model chosen by held-out views.

The rule and its constants are calibration.lens_models' (module docstring there): each model's
score is the pooled RMS of held-out views reprojected at their own best pose under intrinsics
fitted to the other folds [Stone 1974, cross-validation; mrcal's practice of judging a model by
views it was not fitted to]; the simplest model (MODEL_ORDER) not worse than any richer one by
more than NOT_WORSE_REL, and never one above POOR_RMS_PX when a richer one scores better.
With too few views to hold any out (MIN_TRAINING_VIEWS), in-sample RMS is all there is and a
richer model always fits it better: then only the POOR_RMS_PX rule can move the choice past
the pinhole. Omnidir, the slowest to fit (about 24 s of the 36 s that 20 draft board views
took), is scored only where fisheye, the other wide-angle model, beats the pinhole: on a lens
that is not wide-angle its xi goes to 0, where it is the pinhole without k3.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calibration.lens_models import (
    CV_FOLDS,
    MODEL_ORDER,
    NOT_WORSE_REL,
    POOR_RMS_PX,
    fit_model,
    held_out_rms,
)
from workbench.core.errors import UserInputError

MIN_TRAINING_VIEWS = 3      # a fold's training views must determine the intrinsics (intrinsics_fit.MIN_VIEWS)


@dataclass
class ModelChoice:
    """The chosen model, every model's score (pixels; inf where it could not be fitted) and why."""

    model: str
    scores: dict[str, float]
    held_out: bool                       # scores are held-out RMS (else in-sample: too few views)
    why: str
    notes: dict[str, str] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        return {"model": self.model, "score": "held-out view RMS, px" if self.held_out else "in-sample RMS, px",
                "rms_px": {m: (None if not np.isfinite(s) else float(s)) for m, s in self.scores.items()},
                "why": self.why, "notes": dict(self.notes)}


def folds_of(count: int) -> list[list[int]]:
    """View indices per fold: view i in fold i mod k, k = min(CV_FOLDS, count)."""
    k = min(CV_FOLDS, count)
    return [[i for i in range(count) if i % k == f] for f in range(k)]


def held_out_score(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                   model: str) -> float:
    """Pooled RMS (px) over every held-out corner of ``model`` fitted to the other folds."""
    squares, count = 0.0, 0
    for fold in folds_of(len(points)):
        train = [i for i in range(len(points)) if i not in fold]
        fit = fit_model([points[i] for i in train], [corners[i] for i in train], size, flags, model)
        for i in fold:
            rms = held_out_rms(points[i], corners[i], fit)
            squares += rms**2 * len(points[i])
            count += len(points[i])
    return float(np.sqrt(squares / count))


def _in_sample_score(points, corners, size, flags, model: str) -> float:
    return fit_model(points, corners, size, flags, model).rms_px


def pick(scores: dict[str, float], tolerance: float = NOT_WORSE_REL) -> tuple[str, str]:
    """The rule (module docstring) on scores listed simplest first: (model, why). ``tolerance``:
    how much better (relative) a richer model must score to be preferred; infinite for in-sample
    scores, where a richer model always fits better, so that only the POOR_RMS_PX rule applies."""
    names = [m for m in MODEL_ORDER if m in scores]
    for k, name in enumerate(names):
        richer = {m: scores[m] for m in names[k + 1:]}
        if not np.isfinite(scores[name]):
            continue
        better = {m: s for m, s in richer.items() if s * (1 + tolerance) < scores[name]}
        poor = scores[name] > POOR_RMS_PX and any(s < scores[name] for s in richer.values())
        if not better and not poor:
            if not richer:
                return name, f"{name} scores best ({scores[name]:.3f} px)"
            rest = ", ".join(f"{m} {s:.3f}" for m, s in richer.items() if np.isfinite(s))
            margin = f"by over {100 * tolerance:g} %" if np.isfinite(tolerance) else f"while under {POOR_RMS_PX:g} px"
            return name, (f"{name} ({scores[name]:.3f} px) is the simplest model no richer one beats {margin}"
                          + (f" ({rest} px)" if rest else ""))
    finite = {m: s for m, s in scores.items() if np.isfinite(s)}
    if not finite:
        raise UserInputError("no lens model could be fitted to the board views", field="IMAGE",
                             expected="views of the board at several different tilts")
    best = min(finite, key=lambda m: finite[m])
    return best, f"{best} scores best ({finite[best]:.3f} px)"


def _wide_angle(scores: dict[str, float]) -> bool:
    """Whether fisheye beats the pinhole on held-out views by more than NOT_WORSE_REL."""
    return scores.get("fisheye", np.inf) * (1 + NOT_WORSE_REL) < scores.get("pinhole", np.inf)


def choose_model(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
                 flags: int) -> ModelChoice:
    """Score every model on the views and pick one (module docstring)."""
    held_out = len(points) >= MIN_TRAINING_VIEWS + 1
    scores: dict[str, float] = {}
    notes: dict[str, str] = {}
    for model in MODEL_ORDER:
        if model == "omnidir" and held_out and not _wide_angle(scores):
            notes[model] = ("not scored: fisheye, the other wide-angle model, does not beat the pinhole, so the lens is "
                            "not wide-angle (omnidir's folds are three quarters of auto's time)")
            continue
        try:
            score = (held_out_score if held_out else _in_sample_score)(points, corners, size, flags, model)
        except UserInputError as error:
            score, notes[model] = float("inf"), error.reason
        scores[model] = score if np.isfinite(score) else float("inf")
    model, why = pick(scores, NOT_WORSE_REL if held_out else float("inf"))
    kind = f"held-out RMS over {len(folds_of(len(points)))} folds" if held_out else \
        f"in-sample RMS (only {len(points)} views: none can be held out)"
    return ModelChoice(model, scores, held_out, f"{why}; {kind}", notes)
