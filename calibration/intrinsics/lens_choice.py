"""``calibrate intrinsics --model auto``: the lens model chosen by held-out views.

The rule and its constants are calibration.intrinsics.lens_models' (module docstring there): each model's
score is the pooled RMS of held-out views reprojected at their own best pose under intrinsics
fitted to the other folds [Stone 1974, cross-validation; mrcal's practice of judging a model by
views it was not fitted to]; the simplest model (MODEL_ORDER) not worse than any richer one by
more than NOT_WORSE_REL, and never one above POOR_RMS_PX when a richer one scores better.
With too few views to hold any out (MIN_TRAINING_VIEWS), in-sample RMS is all there is and a
richer model always fits it better: then only the POOR_RMS_PX rule can move the choice past
the pinhole. Omnidir, the slowest to fit (about 24 s of the 36 s that 20 draft board views
took), is scored only where fisheye, the other wide-angle model, beats the pinhole: on a lens
that is not wide-angle its xi goes to 0, where it is the pinhole without k3.

Distortion terms (``choose_terms``), within the chosen model, on the same folds: the nested
candidate sets of calibration.intrinsics.lens_models.TERM_CANDIDATES that the flags allow (the pinhole by
default k1, k2 and k1, k2, p1, p2, with --fit-k3 also +k3; the rational model without and with
p1, p2; fisheye k1, k2 -> +k3 -> +k4; omnidir without and with p1, p2), each fitted to the
training folds and scored on the held-out views. The simplest set that no richer set beats is
fitted, the other coefficients held at 0; "beats" is a paired test, not the models' relative
margin: per held-out view, the difference of the two sets' sums of squared corner errors, whose
mean over the views must exceed TERM_T standard errors (a one-sided paired t-test over views
[Dietterich 1998]). Nested sets are scored on the same views and poses, so their difference is
far less noisy than either score, and a term the lens has but the principal point or focal
length partly absorbs changes the held-out RMS by well under the models' 5 % (measured on the
suite's draft dataset, seed 0, tangential terms of 3.6e-4: 0.8 %, paired t 2.25; dropped under
the 5 % margin they left cy 4.2 of its std from the truth, kept 2.0). TERM_T is low because the
costs are unequal: a spurious term adds a little variance that the stated std carries, a dropped
real one a bias that no std covers. The never-above-POOR_RMS_PX rule holds as for the models.
The richest set's per-view errors are the model choice's own (the same folds and fits), so auto
fits only the smaller sets again. Where the chosen set's cross-validation diff then flags it as too
poor for the data, calibration.intrinsics.calibrate fits the first richer set that is not. With too few views
to hold any out, every term the flags free is fitted (in-sample RMS always prefers more terms, so it
cannot choose), as the record says.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calibration.intrinsics.lens_models import (
    CV_FOLDS,
    MODEL_ORDER,
    NOT_WORSE_REL,
    POOR_RMS_PX,
    TERM_CANDIDATES,
    allowed_terms,
    fit_model,
    held_out_rms,
)
from renderer.lens import LENS_MODELS
from workbench.core.errors import UserInputError

MIN_TRAINING_VIEWS = 3      # a fold's training views must determine the intrinsics (intrinsics_fit.MIN_VIEWS)
TERM_T = 1.0                # a richer set of terms must lower the held-out squared error by this many standard errors


@dataclass
class ModelChoice:
    """The chosen model, every model's score (pixels; inf where it could not be fitted) and why."""

    model: str
    scores: dict[str, float]
    held_out: bool                       # scores are held-out RMS (else in-sample: too few views)
    why: str
    notes: dict[str, str] = field(default_factory=dict)
    per_view: dict[str, np.ndarray] = field(default_factory=dict)   # each view's held-out squared error, px^2

    def to_json(self) -> dict[str, Any]:
        return {"model": self.model, "score": "held-out view RMS, px" if self.held_out else "in-sample RMS, px",
                "rms_px": {m: (None if not np.isfinite(s) else float(s)) for m, s in self.scores.items()},
                "why": self.why, "notes": dict(self.notes)}


def folds_of(count: int) -> list[list[int]]:
    """View indices per fold: view i in fold i mod k, k = min(CV_FOLDS, count)."""
    k = min(CV_FOLDS, count)
    return [[i for i in range(count) if i % k == f] for f in range(k)]


def held_out_squares(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                     model: str, terms: Sequence[str] | None = None) -> np.ndarray:
    """Each view's sum of squared corner errors (px^2), held out: ``model`` (fitting ``terms``, default
    those the flags free) fitted to the other folds, the view at its own best pose."""
    squares = np.zeros(len(points))
    for fold in folds_of(len(points)):
        train = [i for i in range(len(points)) if i not in fold]
        fit = fit_model([points[i] for i in train], [corners[i] for i in train], size, flags, model, terms)
        for i in fold:
            squares[i] = held_out_rms(points[i], corners[i], fit) ** 2 * len(points[i])
    return squares


def pooled_rms(squares: np.ndarray, points: Sequence[np.ndarray]) -> float:
    return float(np.sqrt(np.sum(squares) / sum(len(p) for p in points)))


def held_out_score(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                   model: str) -> float:
    """Pooled RMS (px) over every held-out corner of ``model`` fitted to the other folds."""
    return pooled_rms(held_out_squares(points, corners, size, flags, model), points)


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
    per_view: dict[str, np.ndarray] = {}
    for model in MODEL_ORDER:
        if model == "omnidir" and held_out and not _wide_angle(scores):
            notes[model] = ("not scored: fisheye, the other wide-angle model, does not beat the pinhole, so the lens is "
                            "not wide-angle (omnidir's folds are three quarters of auto's time)")
            continue
        try:
            if held_out:
                per_view[model] = held_out_squares(points, corners, size, flags, model)
                score = pooled_rms(per_view[model], points)
            else:
                score = _in_sample_score(points, corners, size, flags, model)
        except UserInputError as error:
            score, notes[model] = float("inf"), error.reason
        scores[model] = score if np.isfinite(score) else float("inf")
    model, why = pick(scores, NOT_WORSE_REL if held_out else float("inf"))
    kind = f"held-out RMS over {len(folds_of(len(points)))} folds" if held_out else \
        f"in-sample RMS (only {len(points)} views: none can be held out)"
    return ModelChoice(model, scores, held_out, f"{why}; {kind}", notes, per_view)


@dataclass
class TermChoice:
    """The distortion terms fitted within one model (module docstring): the candidate sets simplest
    first, their held-out RMS (px; inf where not fitted, None where not scored), the chosen set and why."""

    model: str
    candidates: list[tuple[str, ...]]
    scores: list[float | None]
    chosen: tuple[str, ...]
    held_out: bool
    why: str
    t: dict[str, float] = field(default_factory=dict)   # paired t of each pair tried, "simpler vs richer"
    cross_validation: dict[str, float] = field(default_factory=dict)   # pooled ratios, where a set was too poor

    def to_json(self) -> dict[str, Any]:
        def number(s: float | None) -> float | None:
            return None if s is None or not np.isfinite(s) else float(s)
        return {"candidates": [{"terms": list(c), "rms_px": number(s)} for c, s in zip(self.candidates, self.scores,
                                                                                       strict=True)],
                "score": "held-out view RMS, px" if self.held_out else "not scored (too few views to hold any out)",
                "rule": f"the simplest set that no richer set beats by over {TERM_T:g} standard error of the paired "
                        "per-view difference of held-out squared errors",
                "paired_t": dict(self.t), "chosen": list(self.chosen),
                **({"cross_validation_pooled_ratio": dict(self.cross_validation)} if self.cross_validation else {}),
                "fixed": [n for n in LENS_MODELS[self.model].coefficients if n not in self.chosen],
                "fixed_note": "held at 0: no standard deviation (its std reads 0)", "why": self.why}


def term_candidates(model: str, flags: int) -> list[tuple[str, ...]]:
    """TERM_CANDIDATES[model] within what the flags free (calibration.intrinsics.lens_models.allowed_terms),
    simplest first, without repeats; the last is every term the flags free."""
    allowed = allowed_terms(model, flags)
    out: list[tuple[str, ...]] = []
    for candidate in (*TERM_CANDIDATES[model], allowed):
        terms = tuple(n for n in allowed if n in candidate)
        if terms not in out:
            out.append(terms)
    return out


def label(terms: Sequence[str]) -> str:
    return ", ".join(terms) if terms else "none"


def paired_t(simple: np.ndarray, rich: np.ndarray) -> float:
    """How many standard errors the richer set lowers the held-out squared error by (module docstring)."""
    d = simple - rich
    if not np.all(np.isfinite(d)):
        return float("inf") if np.all(np.isfinite(rich)) else float("-inf")
    se = float(np.std(d, ddof=1)) / np.sqrt(len(d)) if len(d) > 1 else 0.0
    return float(np.sign(d.mean()) * np.inf) if se == 0.0 else float(d.mean() / se)


def _first_unbeaten(candidates: list[tuple[str, ...]], squares: list[np.ndarray], rms: list[float]):
    """The simplest candidate no richer one beats (module docstring); the paired t of every pair tried
    ("simpler vs richer": t)."""
    tried: dict[str, float] = {}
    for k in range(len(candidates)):
        if not np.isfinite(rms[k]):
            continue
        t = {f"{label(candidates[k])} vs {label(c)}": paired_t(squares[k], squares[j])
             for j, c in enumerate(candidates[k + 1:], k + 1)}
        tried |= t
        poor = rms[k] > POOR_RMS_PX and any(s < rms[k] for s in rms[k + 1:])
        if not poor and all(v <= TERM_T for v in t.values()):
            return k, tried
    finite = [k for k in range(len(rms)) if np.isfinite(rms[k])]
    if not finite:
        raise UserInputError("no set of distortion terms could be fitted to the board views", field="IMAGE",
                             expected="views of the board at several different tilts")
    return min(finite, key=lambda k: rms[k]), tried


def choose_terms(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                 model: str, richest: np.ndarray | None = None) -> TermChoice:
    """The distortion terms of ``model`` by held-out views (module docstring). ``richest``: the held-out
    per-view squared errors of every term the flags free, where the model choice has them already."""
    candidates = term_candidates(model, flags)
    if len(candidates) == 1:
        return TermChoice(model, candidates, [None], candidates[0], False,
                          "the only set the flags allow")
    if len(points) < MIN_TRAINING_VIEWS + 1:
        return TermChoice(model, candidates, [None] * len(candidates), candidates[-1], False,
                          f"every term the flags free, as only {len(points)} views leave "
                          "none to hold out")
    squares = []
    for terms in candidates:
        try:
            squares.append(richest if terms == candidates[-1] and richest is not None else
                           held_out_squares(points, corners, size, flags, model, terms))
        except UserInputError:
            squares.append(np.full(len(points), np.inf))
    rms = [pooled_rms(s, points) for s in squares]
    k, t = _first_unbeaten(candidates, squares, rms)
    scores = ", ".join(f"{label(c)} {r:.4f}" for c, r in zip(candidates, rms, strict=True))
    pairs = ", ".join(f"{pair} {value:.2f}" for pair, value in t.items())
    why = (f"the simplest set no richer one beats by over {TERM_T:g} standard error of the "
           f"paired per-view difference (held-out RMS over {len(folds_of(len(points)))} folds: {scores} px; "
           f"paired t: {pairs})")
    return TermChoice(model, candidates, list(rms), candidates[k], True, why, t)
