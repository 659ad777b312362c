"""``calibrate intrinsics --model auto``: the lens model chosen by held-out views.

The rule and its constants are calibration.intrinsics.lens_models' (module docstring there): each model's
score is the pooled RMS of held-out views reprojected at their own best pose under intrinsics
fitted to the other folds [Stone 1974, cross-validation; mrcal's practice of judging a model by
views it was not fitted to]; the simplest model (MODEL_ORDER) not worse than any richer one by
more than NOT_WORSE_REL, and never one above POOR_RMS_PX when a richer one scores better.
With too few views to hold any out (MIN_TRAINING_VIEWS), in-sample RMS is all there is and a
richer model always fits it better: then only the POOR_RMS_PX rule can move the choice past
the pinhole. Each model is scored at the distortion terms its own term choice picks (``choose_terms``
below, on the same folds for every model and set): comparing every model with every term the flags
free set an over-parameterised pinhole (k1, k2, p1, p2) against the fisheye's k1..k4 (measured on the
Sony HX5V views: the pinhole's own k1, k2 score 0.1573 px held out, better than any fisheye set, yet
the fisheye won at 0.1579 against 0.1667). Omnidir, the slowest to fit (about 24 s of the 36 s that
20 draft board views took), is scored only where the lens may be wide-angle: fisheye beats the
pinhole, or fisheye could not be scored (OpenCV's fisheye initialisation fails on some real fisheye
views: measured on BoofCV's fisheye_half, where omnidir scores 0.57 px against the rational model's
2.5), or the pinhole is poor (over POOR_RMS_PX). On a lens that is not wide-angle its xi goes to 0,
where it is the pinhole without k3.

Not physical: a set whose fit (on any fold) folds back inside the image (the projection's distance
from the principal point stops growing with the angle off axis before it reaches the image's edge:
calibration.intrinsics.lens_models.fold_reason) is rejected, scored inf, the reason recorded
(``TermChoice.rejected``, intrinsics.json ``model_choice.terms.rejected`` and the model's note).

Priors with few views: under FEW_VIEWS views, for the models OpenCV's calibrateCamera fits, the
candidates start with the simplest set plus the centre prior (the principal point held at the image
centre, its std CENTRE_PRIOR_REL of the image's size, carried into the other stds:
calibration.intrinsics.lens_models.with_prior_std); the same held-out rule takes it or not.

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

from calibration.intrinsics.fit import FEW_VIEWS
from calibration.intrinsics.lens_models import (
    CENTRE_PRIOR_FLAGS,
    CV_FOLDS,
    MODEL_ORDER,
    NOT_WORSE_REL,
    POOR_RMS_PX,
    PRIOR_MODELS,
    TERM_CANDIDATES,
    allowed_terms,
    fit_model,
    fold_reason,
    held_out_rms,
)
from renderer.lens import LENS_MODELS
from workbench.core.errors import UserInputError


class NotPhysical(UserInputError):
    """A term set whose fit folds back inside the image (calibration.intrinsics.lens_models.fold_reason)."""


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
    terms: dict[str, TermChoice] = field(default_factory=dict)   # each scored model's term choice (held out)

    def to_json(self) -> dict[str, Any]:
        return {"model": self.model, "score": ("held-out view RMS of each model's chosen distortion terms, px"
                                                if self.held_out else "in-sample RMS, px"),
                "rms_px": {m: (None if not np.isfinite(s) else float(s)) for m, s in self.scores.items()},
                "why": self.why, "notes": dict(self.notes)}


def folds_of(count: int) -> list[list[int]]:
    """View indices per fold: view i in fold i mod k, k = min(CV_FOLDS, count)."""
    k = min(CV_FOLDS, count)
    return [[i for i in range(count) if i % k == f] for f in range(k)]


def held_out_squares(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                     model: str, terms: Sequence[str] | None = None) -> np.ndarray:
    """Each view's sum of squared corner errors (px^2), held out: ``model`` (fitting ``terms``, default
    those the flags free) fitted to the other folds, the view at its own best pose. NotPhysical where a
    fold's fit folds back inside the image (calibration.intrinsics.lens_models.fold_reason)."""
    squares = np.zeros(len(points))
    for fold in folds_of(len(points)):
        train = [i for i in range(len(points)) if i not in fold]
        fit = fit_model([points[i] for i in train], [corners[i] for i in train], size, flags, model, terms)
        reason = fold_reason(fit, size)
        if reason is not None:
            raise NotPhysical(reason, field="IMAGE")
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
    """Whether the lens may be wide-angle, so that omnidir is worth scoring: fisheye beats the pinhole on
    held-out views by more than NOT_WORSE_REL, or fisheye could not be scored (a fisheye fit that fails,
    as OpenCV's initialisation does on some real fisheye views, says nothing about the lens), or the
    pinhole is poor (over POOR_RMS_PX)."""
    fisheye, pinhole = scores.get("fisheye", np.inf), scores.get("pinhole", np.inf)
    return not np.isfinite(fisheye) or fisheye * (1 + NOT_WORSE_REL) < pinhole or pinhole > POOR_RMS_PX


def _score_model(points, corners, size, flags, model: str, held_out: bool) -> tuple[float, TermChoice | None]:
    """A model's score: held out, that of the distortion terms its own term choice picks (``choose_terms``,
    the same folds for every model and set), so that models are compared at their chosen sets, never one
    over-parameterised against another's lean set; in sample, every term the flags free."""
    if not held_out:
        return _in_sample_score(points, corners, size, flags, model), None
    terms = choose_terms(points, corners, size, flags, model)
    if terms.scores[terms.index] is None:   # the only set the flags allow: not scored by the term choice
        extra = CENTRE_PRIOR_FLAGS if terms.prior else 0
        squares = held_out_squares(points, corners, size, flags | extra, model, terms.chosen)
        terms.scores[terms.index], terms.squares = pooled_rms(squares, points), [squares]
    score = terms.scores[terms.index]
    return (float(score) if score is not None else float("inf")), terms


def choose_model(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int],
                 flags: int) -> ModelChoice:
    """Score every model on the views and pick one (module docstring)."""
    held_out = len(points) >= MIN_TRAINING_VIEWS + 1
    scores: dict[str, float] = {}
    notes: dict[str, str] = {}
    term_choices: dict[str, TermChoice] = {}
    for model in MODEL_ORDER:
        if model == "omnidir" and held_out and not _wide_angle(scores):
            notes[model] = ("not scored: fisheye, the other wide-angle model, does not beat the pinhole and the pinhole "
                            "is not poor, so the lens is not wide-angle (omnidir's folds are three quarters of auto's "
                            "time)")
            continue
        try:
            score, terms = _score_model(points, corners, size, flags, model, held_out)
            if terms is not None:
                term_choices[model] = terms
                if terms.rejected:
                    notes[model] = "; ".join(f"{k}: {v}" for k, v in terms.rejected.items())
        except UserInputError as error:
            score, notes[model] = float("inf"), error.reason
        scores[model] = score if np.isfinite(score) else float("inf")
    model, why = pick(scores, NOT_WORSE_REL if held_out else float("inf"))
    kind = (f"held-out RMS of each model's chosen terms over {len(folds_of(len(points)))} folds" if held_out else
            f"in-sample RMS (only {len(points)} views: none can be held out)")
    return ModelChoice(model, scores, held_out, f"{why}; {kind}", notes, term_choices)


@dataclass
class TermChoice:
    """The distortion terms fitted within one model (module docstring): the candidate sets simplest
    first (``priors``: whether each holds the principal point at the image centre as a prior), their
    held-out RMS (px; inf where not fitted or not physical, None where not scored), the chosen set and why."""

    model: str
    candidates: list[tuple[str, ...]]
    scores: list[float | None]
    chosen: tuple[str, ...]
    held_out: bool
    why: str
    t: dict[str, float] = field(default_factory=dict)   # paired t of each pair tried, "simpler vs richer"
    cross_validation: dict[str, float] = field(default_factory=dict)   # pooled ratios, where a set was too poor
    priors: list[bool] = field(default_factory=list)    # per candidate: the centre prior (CENTRE_PRIOR_FLAGS)
    index: int = -1                                      # the chosen candidate
    rejected: dict[str, str] = field(default_factory=dict)   # candidates not fitted or not physical, and why
    squares: list[np.ndarray] = field(default_factory=list)  # per candidate, each view's held-out squared error

    def __post_init__(self) -> None:
        self.priors = self.priors or [False] * len(self.candidates)
        if self.index < 0:
            self.index = self.candidates.index(self.chosen)

    @property
    def prior(self) -> bool:
        """Whether the chosen candidate holds the principal point at the image centre (a prior)."""
        return self.priors[self.index]

    def name(self, k: int) -> str:
        return label(self.candidates[k]) + (" + centre prior" if self.priors[k] else "")

    def choose(self, k: int) -> None:
        self.index, self.chosen = k, self.candidates[k]

    def to_json(self) -> dict[str, Any]:
        def number(s: float | None) -> float | None:
            return None if s is None or not np.isfinite(s) else float(s)
        candidates = [{"terms": list(c), "rms_px": number(s)} | ({"priors": ["principal_point"]} if p else {})
                      for c, s, p in zip(self.candidates, self.scores, self.priors, strict=True)]
        return {"candidates": candidates,
                "score": "held-out view RMS, px" if self.held_out else "not scored (too few views to hold any out)",
                "rule": f"the simplest set that no richer set beats by over {TERM_T:g} standard error of the paired "
                        "per-view difference of held-out squared errors",
                "paired_t": dict(self.t), "chosen": list(self.chosen), "priors": ["principal_point"] if self.prior else [],
                **({"cross_validation_pooled_ratio": dict(self.cross_validation)} if self.cross_validation else {}),
                **({"rejected": dict(self.rejected)} if self.rejected else {}),
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
    if se == 0.0:
        return 0.0 if d.mean() == 0.0 else float(np.sign(d.mean()) * np.inf)
    return float(d.mean() / se)


def _first_unbeaten(names: list[str], squares: list[np.ndarray], rms: list[float]):
    """The simplest candidate no richer one beats (module docstring); the paired t of every pair tried
    ("simpler vs richer": t)."""
    tried: dict[str, float] = {}
    for k in range(len(names)):
        if not np.isfinite(rms[k]):
            continue
        t = {f"{names[k]} vs {c}": paired_t(squares[k], squares[j])
             for j, c in enumerate(names[k + 1:], k + 1) if np.isfinite(rms[j])}
        tried |= t
        poor = rms[k] > POOR_RMS_PX and any(s < rms[k] for s in rms[k + 1:])
        if not poor and all(v <= TERM_T for v in t.values()):
            return k, tried
    finite = [k for k in range(len(rms)) if np.isfinite(rms[k])]
    if not finite:
        raise UserInputError("no set of distortion terms could be fitted to the board views", field="IMAGE",
                             expected="views of the board at several different tilts")
    return min(finite, key=lambda k: rms[k]), tried


def _candidates(model: str, flags: int, views: int) -> tuple[list[tuple[str, ...]], list[bool]]:
    """term_candidates, and with fewer than FEW_VIEWS views (a model whose fit honours the flag, the principal
    point not already held) first the simplest set with the principal point held at the image centre, the
    prior of calibration.intrinsics.lens_models.CENTRE_PRIOR_REL: the simplest of all (fewest free parameters)."""
    candidates = term_candidates(model, flags)
    priors = [False] * len(candidates)
    if views < FEW_VIEWS and model in PRIOR_MODELS and not flags & CENTRE_PRIOR_FLAGS:
        candidates, priors = [candidates[0], *candidates], [True, *priors]
    return candidates, priors


def _held_out_or_why(points, corners, size, flags, model, terms) -> tuple[np.ndarray, str | None]:
    """held_out_squares, or infinite errors and why (a fit that fails or folds back inside the image)."""
    try:
        return held_out_squares(points, corners, size, flags, model, terms), None
    except UserInputError as error:
        return np.full(len(points), np.inf), error.reason


def choose_terms(points: Sequence[np.ndarray], corners: Sequence[np.ndarray], size: tuple[int, int], flags: int,
                 model: str, richest: np.ndarray | None = None) -> TermChoice:
    """The distortion terms of ``model`` (and with few views the centre prior) by held-out views (module
    docstring). ``richest``: the held-out per-view squared errors of every term the flags free, where known.
    A set whose fit folds back inside the image is rejected as not physical, the reason recorded."""
    candidates, priors = _candidates(model, flags, len(points))
    if len(candidates) == 1:
        return TermChoice(model, candidates, [None], candidates[0], False, "the only set the flags allow")
    if len(points) < MIN_TRAINING_VIEWS + 1:
        plain = len(candidates) - 1
        return TermChoice(model, candidates, [None] * len(candidates), candidates[plain], False,
                          f"every term the flags free, as only {len(points)} views leave none to hold out",
                          priors=priors, index=plain)
    choice = TermChoice(model, candidates, [], candidates[-1], True, "", priors=priors, index=len(candidates) - 1)
    for k, terms in enumerate(candidates):
        if k == len(candidates) - 1 and richest is not None:
            choice.squares.append(richest)
            continue
        extra = CENTRE_PRIOR_FLAGS if priors[k] else 0
        squares, why = _held_out_or_why(points, corners, size, flags | extra, model, terms)
        choice.squares.append(squares)
        if why is not None:
            choice.rejected[choice.name(k)] = why
    rms = [pooled_rms(s, points) for s in choice.squares]
    names = [choice.name(k) for k in range(len(candidates))]
    if not any(np.isfinite(rms)) and choice.rejected:
        raise UserInputError("no set of distortion terms could be fitted to the board views: "
                             + "; ".join(f"{n}: {w}" for n, w in choice.rejected.items()), field="IMAGE")
    k, choice.t = _first_unbeaten(names, choice.squares, rms)
    choice.scores = list(rms)
    choice.choose(k)
    scores = ", ".join(f"{n} {r:.4f}" for n, r in zip(names, rms, strict=True))
    pairs = ", ".join(f"{pair} {value:.2f}" for pair, value in choice.t.items())
    rejected = "; rejected: " + "; ".join(f"{n}: {w}" for n, w in choice.rejected.items()) if choice.rejected else ""
    choice.why = (f"the simplest set no richer one beats by over {TERM_T:g} standard error of the "
                  f"paired per-view difference (held-out RMS over {len(folds_of(len(points)))} folds: {scores} px; "
                  f"paired t: {pairs}){rejected}")
    return choice
