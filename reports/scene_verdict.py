"""The verdict of a scene fit: is the photo consistent with the scene file, and if not, is it the model or the camera?

The test (stated, with its numbers written beside the verdict): the scene file's values
(the nested model, H0) against the fitted ones, on the photos' band edges, by the
likelihood ratio of Gaussian edge residuals [Wilks 1938]:

    LR = r0^T S^-1 r0 - r1^T S^-1 r1,   LR ~ chi^2(k) under H0,

with r0, r1 the residuals (predicted minus photo edge, px, and the photo's rim points'
distances from the predicted rim) at the file's and the fitted values, k the number of
fitted components and S the residuals' covariance. Two covariances:

* noise only: S = sigma^2 W^-1, sigma the noise *measured* at the fit (1.4826 MAD of the
  fitted residuals, band edges and rim points apart) and W the fit's robust (Cauchy) weights, so that edges the fit
  treats as outliers count as little here;
* noise and camera: S plus C, the edges' covariance from the calibration's standard
  deviations: the residuals' changes over cameras drawn within them
  (reports.camera_draws.draw_cameras, ``CAMERA_DRAWS`` per photo).

Decision, at ``ALPHA`` (p-values of chi^2(k)):

* ``consistent``: the noise-only test keeps H0 (p >= ALPHA);
* ``camera``: the noise-only test rejects H0 and the test with the camera's uncertainty
  keeps it: the disagreement fits within what the calibration leaves open;
* ``model``: both reject H0, some parameter moved by more than ``MOVED_SIGMAS`` of its
  standard deviation, and the fitted scene's residuals are at the level of an unperturbed
  scene (median |r| <= ``REMOVED_MEDIAN_PX``): those parameters are named;
* ``unexplained``: otherwise; the largest residuals are listed with where they are.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2

from reports.camera_draws import CAMERA_STD_KEYS, draw_cameras
from reports.scene_fit import SceneFitResult, cauchy_weights
from reports.scene_fit_model import EdgeModel, ObservedEdges

ALPHA = 1e-3
MOVED_SIGMAS = 3.0
REMOVED_MEDIAN_PX = 0.5  # the prediction-vs-photo median of unperturbed test datasets: 0.34 px (seed 0, 640 x 480)
CAMERA_DRAWS = 8
LISTED_RESIDUALS = 10


def camera_edge_covariance(model: EdgeModel, values: np.ndarray, observed: ObservedEdges,
                           draws: int = CAMERA_DRAWS, seed: int = 0) -> np.ndarray | None:
    """The edges' covariance (px^2) from the cameras' standard deviations, or None when the
    calibration gives none: the mean outer product of the residuals' changes over drawn cameras."""
    if not any(isinstance(v.camera_std.get(k), (int, float)) for v in model.views for k in CAMERA_STD_KEYS):
        return None
    base = model.residuals(values, observed)
    drawn = [draw_cameras(v.camera, v.camera_std, draws, seed + i) for i, v in enumerate(model.views)]
    changes = []
    for d in range(draws):
        views = [dataclasses.replace(v, camera=drawn[i][d]) for i, v in enumerate(model.views)]
        shifted = EdgeModel(model.spec, model.table, views, supersample=model.supersample, step_nm=model.step_nm,
                            efficiency=model.efficiency)
        changes.append(shifted.residuals(values, observed) - base)
    delta = np.array(changes)
    return delta.T @ delta / draws


@dataclass
class LikelihoodRatio:
    statistic: float
    dof: int
    p_value: float

    def to_json(self) -> dict[str, float]:
        return {"statistic": self.statistic, "dof": self.dof, "p_value": self.p_value}


def likelihood_ratio(r0: np.ndarray, r1: np.ndarray, S: np.ndarray, dof: int) -> LikelihoodRatio:
    """LR = r0^T S^-1 r0 - r1^T S^-1 r1 and its chi^2(dof) p-value."""
    solve = np.linalg.pinv(S, hermitian=True)
    statistic = float(r0 @ solve @ r0 - r1 @ solve @ r1)
    return LikelihoodRatio(statistic, dof, float(chi2.sf(max(statistic, 0.0), dof)))


def _summary(r: np.ndarray) -> dict[str, Any]:
    a = np.abs(r)
    return {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "count": int(len(a))}


def _largest(result: SceneFitResult, views: list[str]) -> list[dict[str, Any]]:
    order = np.argsort(-np.abs(result.residuals_fitted[:result.observed.edge_count]))[:LISTED_RESIDUALS]
    out = []
    for i in order:
        key, edge = result.observed.keys[i], result.observed.edges[i]
        kind, profile, m, channel, band, side = key.key
        out.append({"photo": views[key.view], "kind": kind, "at": edge.label, "order": m, "channel": channel,
                    "side": side, "x": edge.x, "y": edge.y, "residual_px": float(result.residuals_fitted[i])})
    return out


def verdict(result: SceneFitResult, labels: list[str], names: list[str], views: list[str],
            camera_covariance: np.ndarray | None) -> dict[str, Any]:
    """report.json's and scene_fit.json's ``verdict`` (module docstring). ``labels``: each
    fitted component's name (FitTable.labels); ``names`` the parameter each belongs to."""
    k = len(result.values)
    w = cauchy_weights(result.residuals_fitted, result.sigma)
    noise = np.diag(result.sigma**2 / w)
    edges = result.observed.edge_count
    test_noise = likelihood_ratio(result.residuals_nominal, result.residuals_fitted, noise, k)
    test_camera = None if camera_covariance is None else likelihood_ratio(
        result.residuals_nominal, result.residuals_fitted, noise + camera_covariance, k)
    z = (result.values - result.nominal) / np.maximum(result.std, 1e-300)
    moved = [i for i in range(k) if abs(z[i]) > MOVED_SIGMAS]
    fitted_median = float(np.median(np.abs(result.residuals_fitted[:edges])))
    if test_noise.p_value >= ALPHA:
        kind, why = "consistent", "the scene file's values explain the band edges as well as the fitted ones do"
    elif test_camera is not None and test_camera.p_value >= ALPHA:
        kind, why = "camera", ("the disagreement lies within the calibration's uncertainty of the camera "
                               "(its standard deviations of " + ", ".join(CAMERA_STD_KEYS) + ")")
    elif moved and fitted_median <= REMOVED_MEDIAN_PX:
        kind, why = "model", "scene parameters had to move by more than 3 standard deviations, and moving them " \
                             "removes the disagreement"
    else:
        kind, why = "unexplained", ("neither the camera's uncertainty nor the free scene parameters explain the "
                                    "band edges" if not moved else
                                    "the fitted scene leaves residuals above the unperturbed level")
    out: dict[str, Any] = {
        "verdict": kind, "why": why,
        "test": {"method": "likelihood ratio, nominal (file) against fitted scene, on the photos' band edges; "
                           "chi-square with one degree of freedom per fitted component",
                 "alpha": ALPHA, "edge_noise_px": result.sigma_px, "edges": edges,
                 "rim_points": len(result.residuals_fitted) - edges,
                 "rim_noise_px": float(result.sigma[edges]) if len(result.sigma) > edges else None,
                 "noise_only": test_noise.to_json(),
                 "noise_and_camera": None if test_camera is None else test_camera.to_json()},
        "moved_sigmas": MOVED_SIGMAS,
        "parameters": [{"name": names[i], "component": labels[i], "nominal": float(result.nominal[i]),
                        "fitted": float(result.values[i]), "std": float(result.std[i]), "sigmas": float(z[i])}
                       for i in moved] if kind == "model" else [],
        "residuals_before_px": _summary(result.residuals_nominal[:edges]),
        "residuals_after_px": _summary(result.residuals_fitted[:edges]),
        "rim_residuals_before_px": _summary(result.residuals_nominal[edges:]) if len(result.sigma) > edges else None,
        "rim_residuals_after_px": _summary(result.residuals_fitted[edges:]) if len(result.sigma) > edges else None,
    }
    if kind == "unexplained":
        out["largest_residuals"] = _largest(result, views)
    return out
