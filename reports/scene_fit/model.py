"""The scene fit's forward model: where the CD's band edges fall for given scene parameters.

No renderer in the loop: for parameter values (renderer.fit_parameters, fit coordinates)
the scene is changed (the CD's placement, the light, the grating's period), the
grating-equation prediction weighted by the RCWA efficiency is made for each photo's
fitted camera (renderer.trace.prediction), sampled on that photo's fixed polar grids
(reports.fringes.polar, set once from the scene file's CD, so that the same edge keys and pixel
lines serve every evaluation) and its band edges found (reports.fringes.band_edges). A residual is the
predicted edge's position minus the photo's along the profile, in pixels.

The photo's edges are found with the windows of a prediction (fringes.find_edges): the fit
measures them once per round with the round's starting values (ObservedEdges), and they
stay fixed while the optimiser moves the prediction.

A fitted layer thickness or stripe width (the groove's depth and width) reads its efficiencies
from tables built on a grid of their values (reports.scene_fit.structure_tables). Approximation, stated: otherwise the
efficiency table is the scene file's (its period and depth);
a fitted period moves the orders' directions exactly (the grating equation) but their
efficiencies are read at the table's period, a change of eta by a few per cent for a
period a few per cent off, which moves a half-maximum edge by far less than its slope's
pixel.
"""

from __future__ import annotations

import copy
import dataclasses
import os
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import cv2
import numpy as np

from renderer.camera import CameraModel
from renderer.fit_parameters import FitTable
from renderer.trace.efficiency_weights import Efficiency, scene_efficiency
from renderer.trace.prediction import PREDICTION_STEP_NM, Prediction, cd_geometry, predict
from reports.compare.images import Photo
from reports.fringes import band_edges as fringes
from reports.fringes import cd_shadow as rim_clutter
from reports.fringes import polar, rim
from reports.scene_fit.apply import AppliedScene, apply_values
from reports.scene_fit.bias import ViewBias, band_offsets, render_photo, rim_offsets, usable_render
from reports.scene_fit.structure_tables import STRUCTURE_KINDS, BlendedEfficiency, StructureEfficiencies
from workbench.core.errors import UserInputError

FIT_SUPERSAMPLE = 1  # sub-rays per pixel axis in the fit's predictions (the report's is 2)
RIM_POINTS_USED = 90  # photo rim points per view (of reports.fringes.rim's 720 searches; neighbours share pixels)
RIM_BLOCK = 8
RIM_CLIP_PX = 2  # rim points this close to a clipped pixel are left out (photo_rim_points)
FIT_THREADS = max(1, min(4, os.cpu_count() or 1))  # independent evaluations at once (EdgeModel.residuals_many)
NOISE_GROUPS = ("circle", "radius", "rim")  # ObservedEdges.groups: band edges by their grid's kind, rim points
MISSING_EDGE_PX = 4.0  # the residual of an observed edge the prediction no longer shows (a robust loss caps it)


@dataclass
class View:
    """One photo in the fit: its fitted camera, the decoded photo and its fixed grids."""

    name: str
    camera: CameraModel
    photo: Photo
    grids: tuple[polar.PolarGrid, ...]
    camera_std: dict
    correlation_px: float = fringes.NOISE_CORRELATION_PX
    rim_points: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 2)))  # the photo's CD rim (px)
    render: np.ndarray | None = None  # linear RGB of the scene file through this camera (reports.scene_fit.bias)
    render_variance: np.ndarray | None = None  # its per-pixel variance between passes (renderer.render), if written


@dataclass(frozen=True)
class EdgeKey:
    view: int
    key: tuple


@dataclass
class ObservedEdges:
    """The photos' edges of quality ok, with the prediction's edge key (fixed for a round)."""

    keys: list[EdgeKey]
    edges: list[fringes.Edge]
    grids: list[polar.PolarGrid]
    rims: list[tuple[int, np.ndarray]] = dataclasses.field(default_factory=list)  # (view, photo rim points)
    bias: np.ndarray | None = None  # per residual, the forward model's offset measured on a render (scene_fit_bias)

    def __len__(self) -> int:
        """The number of residuals: band edges, then rim points."""
        return len(self.keys) + sum(len(points) for _, points in self.rims)

    @property
    def edge_count(self) -> int:
        return len(self.keys)

    def subsample(self, fraction: float, seed: int) -> ObservedEdges:
        """A share ``fraction`` of the band edges, drawn without replacement (the rim points all kept)."""
        if fraction >= 1.0:
            return self
        count = max(1, int(round(fraction * len(self.keys))))
        rows = np.sort(np.random.default_rng(seed).choice(len(self.keys), count, replace=False))
        kept = np.concatenate([rows, np.arange(len(self.keys), len(self))])
        return ObservedEdges([self.keys[i] for i in rows], [self.edges[i] for i in rows], [self.grids[i] for i in rows],
                             self.rims, None if self.bias is None else self.bias[kept])

    def without(self, keys: set) -> ObservedEdges:
        """These edges without the given EdgeKeys (the rim points all kept)."""
        if not keys:
            return self
        rows = np.array([i for i, k in enumerate(self.keys) if k not in keys], int)
        kept = np.concatenate([rows, np.arange(len(self.keys), len(self))])
        return ObservedEdges([self.keys[i] for i in rows], [self.edges[i] for i in rows], [self.grids[i] for i in rows],
                             self.rims, None if self.bias is None else self.bias[kept])

    def groups(self) -> np.ndarray:
        """Per residual, its noise group (``NOISE_GROUPS``: band edges along circles, along radii,
        rim points), each with its own measured noise. Band edges along radii scatter far more
        than along circles: at the true scene of six unperturbed draft datasets (seeds 0-5) the
        residuals' robust spread was 0.20-0.46 px along circles (1-1.6 times the edges' own
        position uncertainty) and 0.71-1.8 px along radii (2.6-10 times): a radius crosses the
        band's gentle colour ramp, whose half-maximum crossing moves with the ramp's shape. One
        noise for both weighted the radius edges, which carry most of the period, several times
        above their worth, and the period's std came out too small (seed 4: 2.0 % off at 3.1 of
        its std)."""
        kind = np.array([NOISE_GROUPS.index(k.key[0]) for k in self.keys], int)
        return np.concatenate([kind, np.full(len(self) - len(self.keys), NOISE_GROUPS.index("rim"), int)])

    def blocks(self, by: str = "profile") -> list[list[int]]:
        """Residuals that share an error: by ``profile``, a profile's edges (its pixels' noise);
        by ``band``, one band's edges of an order along every profile, all channels (the forward
        model's own error at an edge, which changes slowly along the band); and ``RIM_BLOCK``
        neighbouring rim points either way."""
        groups: dict[tuple, list[int]] = {}
        for i, key in enumerate(self.keys):
            kind, profile, order, _, band, side = key.key
            groups.setdefault((key.view, kind, profile) if by == "profile" else (key.view, kind, order, band, side),
                              []).append(i)
        at = len(self.keys)
        for v, points in self.rims:
            for start in range(0, len(points), RIM_BLOCK):
                groups[("rim", v, start)] = list(range(at + start, at + min(start + RIM_BLOCK, len(points))))
            at += len(points)
        return list(groups.values())

    def of_view(self, view: int) -> tuple[ObservedEdges, np.ndarray]:
        """One view's share, its keys renumbered as view 0 (for a model of that view alone), and
        the rows of its residuals in this set's residual vector (band edges, then rim points)."""
        rows = [i for i, key in enumerate(self.keys) if key.view == view]
        at, rims = len(self.keys), []
        for v, points in self.rims:
            if v == view:
                rows.extend(range(at, at + len(points)))
                rims.append((0, points))
            at += len(points)
        picked = [i for i in rows if i < len(self.keys)]
        share = ObservedEdges([EdgeKey(0, self.keys[i].key) for i in picked], [self.edges[i] for i in picked],
                              [self.grids[i] for i in picked], rims, None if self.bias is None else self.bias[rows])
        return share, np.array(rows, int)

    def profiles(self) -> dict[tuple[int, str], set[int]]:
        """The profiles the edges lie on, by (view, grid kind)."""
        out: dict[tuple[int, str], set[int]] = {}
        for key in self.keys:
            out.setdefault((key.view, key.key[0]), set()).add(key.key[1])
        return out



def view_grids(spec, camera: CameraModel) -> tuple[polar.PolarGrid, ...]:
    """The polar grids of the scene file's CD seen by ``camera`` (kept fixed during the fit)."""
    return polar.standard_grids(camera, cd_geometry(spec))


def photo_rim_points(photo: Photo, camera: CameraModel, spec) -> np.ndarray:
    """The CD's rim in the photo (reports.fringes.rim: strongest gradient along the expected rim's normals),
    ``RIM_POINTS_USED`` searched, those where the CD's shadow makes an edge nearby
    dropped (reports.fringes.cd_shadow), then points off the others' ellipse by more than ``RIM_OUTLIER_PX``,
    then points within ``RIM_CLIP_PX`` of a clipped pixel: where the light's band makes the disc
    brighter than the sensor's white, the clipped side flattens the blurred edge and its strongest
    gradient moves toward the unclipped side. Measured on the draft dataset of a CD tilted 2 deg more
    (seed 0), whose view1 is clipped over the far arc: those points sat up to 1.7 px off the true
    rim (view0's, from filled brackets, within 0.5 px), and the rim-only tilt fitted 0.80 deg off
    sideways with them, 0.07 deg without.

    The rim searched for and compared with is the grating's (the disc's edge): the
    transparent top shows a far weaker edge (measured with the true camera on a synthetic
    photo: the grating's circle within 0.2-0.4 px by sector, the top's 0.5-1 px off)."""
    cd = cd_geometry(spec)
    expected, clear = rim_clutter.clear_rim(spec, camera, cd, RIM_POINTS_USED, rim.RIM_SEARCH_PX)
    found = rim.rim_points(photo.rgb, expected[clear])
    if len(found) < rim.RIM_MIN_POINTS:
        return np.zeros((0, 2))
    (cx, cy), (w, h), angle = cv2.fitEllipse(found.astype(np.float32))
    ellipse = rim.Rim((float(cx), float(cy)), (float(w), float(h)), float(angle), len(found), 0.0)
    found = found[np.abs(rim.ellipse_residual(found, ellipse)) <= rim.RIM_OUTLIER_PX]
    return found[~near_clipped(photo.clipped, found, RIM_CLIP_PX)]


def near_clipped(clipped: np.ndarray, points: np.ndarray, radius_px: int) -> np.ndarray:
    """Whether each point (N, 2) lies within ``radius_px`` (a square) of a clipped pixel."""
    grown = cv2.dilate(clipped.astype(np.uint8), np.ones((2 * radius_px + 1, 2 * radius_px + 1), np.uint8)) > 0
    pixel = np.round(points).astype(int)
    rows = np.clip(pixel[:, 1], 0, grown.shape[0] - 1)
    cols = np.clip(pixel[:, 0], 0, grown.shape[1] - 1)
    return grown[rows, cols]


def rim_residuals(camera: CameraModel, cd, points: np.ndarray) -> np.ndarray:
    """Signed distance (px, outward positive) of the photo's rim points from the predicted rim's
    curve (the grating's edge, as ``photo_rim_points`` measures it)."""
    curve = camera.project(cd.rim_points())
    nearest = np.argmin(((points[:, None, :] - curve[None]) ** 2).sum(axis=2), axis=1)
    normal = rim.outward_normals(curve)
    return np.einsum("ij,ij->i", points - curve[nearest], normal[nearest])


def sampled_prediction(pred: Prediction, grid: polar.PolarGrid) -> np.ndarray:
    """The prediction's lit fractions sampled on ``grid`` (orders, 3, radii, azimuths), as images are."""
    frame = (pred.camera.height, pred.camera.width)
    return np.stack([polar.sample_crop(lit.transpose(1, 2, 0), (pred.x0, pred.y0), frame, grid, robust=True)
                     for lit in pred.lit]).transpose(0, 3, 1, 2)  # 3 channels per remap (OpenCV's bilinear path)


class EdgeModel:
    """Predicted band edges per view for parameter values; the photos' edges; residuals."""

    def __init__(self, spec, table: FitTable, views: list[View], *, supersample: int = FIT_SUPERSAMPLE,
                 step_nm: float = PREDICTION_STEP_NM, efficiency: Efficiency | None = None):
        self.spec, self.table, self.views = spec, table, views
        self.supersample, self.step_nm = supersample, step_nm
        self.efficiency = efficiency if efficiency is not None else scene_efficiency(spec)
        fields = [p for p in table.free if p.kind in STRUCTURE_KINDS]
        if len(fields) > 2 or any(p.cd_index != 0 for p in fields):
            raise UserInputError("the scene fit varies at most two structure fields (a layer's thickness, a stripe's "
                                 "width), of cd[0]", file=spec.source, field="fit", got=[p.name for p in fields])
        self.structure = StructureEfficiencies(spec, fields, [v.camera for v in views]) if fields else None
        self.evaluations = 0
        self.seconds = 0.0
        self._bias: list[ViewBias | None] | None = None  # measured at the first observed_edges
        self.bias_notes: list[dict] = [{} for _ in views]  # per view, what its render measured, or why not used

    def with_views(self, views: list[View]) -> EdgeModel:
        """The same model (its efficiencies shared, not rebuilt) for other views; its evaluations
        and seconds are counted apart."""
        other = copy.copy(self)
        other.views, other.evaluations, other.seconds = views, 0, 0.0
        other._bias = None  # measured again for those views if asked (observed_edges); residuals read ObservedEdges.bias
        return other

    def residuals_many(self, calls: Sequence[tuple[np.ndarray, ObservedEdges, list[View] | None]]) -> list[np.ndarray]:
        """Each call's residuals (values, observed edges, and views in place of this model's, or
        None), on ``FIT_THREADS`` threads: the evaluations are independent and deterministic, so
        the answers are those of one thread, in order; numpy runs most of an evaluation without
        the interpreter's lock (2 threads: 1.42 times one on a 978 x 734 photo, 2 cores). Each
        runs on its own copy (with_views); their evaluations and seconds are counted here."""
        def one(call: tuple[np.ndarray, ObservedEdges, list[View] | None]) -> tuple[np.ndarray, EdgeModel]:
            values, observed, views = call
            model = self.with_views(self.views if views is None else views)
            return model.residuals(values, observed), model

        with ThreadPoolExecutor(FIT_THREADS) as pool:
            done = list(pool.map(one, calls))
        for _, model in done:
            self.evaluations, self.seconds = self.evaluations + model.evaluations, self.seconds + model.seconds
        return [r for r, _ in done]

    def applied(self, values: np.ndarray) -> AppliedScene:
        return apply_values(self.spec, self.table, values)

    def predictions(self, values: np.ndarray) -> list[Prediction | None]:
        """One prediction per view (None where the changed CD leaves that camera's view)."""
        applied = self.applied(values)
        cd = cd_geometry(applied.spec)
        period = applied.period_um(0)
        if period is not None:
            cd = dataclasses.replace(cd, period_um=period)
        efficiency: Efficiency | BlendedEfficiency = self.efficiency
        if self.structure is not None:
            efficiency = self.structure.at(applied.structure_changes.get(0, {}))
        out: list[Prediction | None] = []
        for view in self.views:
            try:
                out.append(predict(applied.spec, view.camera, supersample=self.supersample, step_nm=self.step_nm,
                                   efficiency=efficiency, geometry=cd))  # type: ignore[arg-type]
            except ValueError:  # UserInputError: the CD left the view
                out.append(None)
        return out

    def predicted_edges(self, values: np.ndarray, profiles: dict[tuple[int, str], set[int]] | None = None
                        ) -> dict[EdgeKey, fringes.Edge]:
        """Every view's predicted band edges (all qualities), by key; ``profiles``: only those
        profiles, by (view, grid kind)."""
        started = time.perf_counter()
        found: dict[EdgeKey, fringes.Edge] = {}
        for v, (view, pred) in enumerate(zip(self.views, self.predictions(values), strict=True)):
            if pred is None:
                continue
            for grid in view.grids:
                wanted = None if profiles is None else profiles.get((v, grid.kind), set())
                if wanted is not None and not wanted:
                    continue
                for e in fringes.find_edges(grid, sampled_prediction(pred, grid), pred.orders, profiles=wanted):
                    if np.isfinite(e.position):
                        found[EdgeKey(v, e.key())] = e
        self.evaluations += 1
        self.seconds += time.perf_counter() - started
        return found

    def observed_edges(self, values: np.ndarray) -> ObservedEdges:
        """The photos' edges of quality ok, found in the windows of the prediction at ``values``."""
        keys, edges, grids = [], [], []
        for v, (view, pred) in enumerate(zip(self.views, self.predictions(values), strict=True)):
            if pred is None:
                continue
            for grid in view.grids:
                sampled = sampled_prediction(pred, grid)
                for e in fringes.find_edges(grid, sampled, pred.orders, view.photo.rgb, view.photo.clipped,
                                            view.correlation_px):
                    if e.quality == "ok":
                        keys.append(EdgeKey(v, e.key()))
                        edges.append(e)
                        grids.append(grid)
        rims = [(v, view.rim_points) for v, view in enumerate(self.views) if len(view.rim_points)]
        biases = self.view_biases()
        if not any(b is not None for b in biases):
            return ObservedEdges(keys, edges, grids, rims)
        none = ViewBias({}, np.zeros(0), np.zeros(0), np.zeros(2))
        bias = [(biases[k.view] or none).edge(k.key) for k in keys]
        bias += [value for v, points in rims for value in (biases[v] or none).rim(points)]
        return ObservedEdges(keys, edges, grids, rims, np.asarray(bias, float))

    def view_biases(self) -> list[ViewBias | None]:
        """Per view, the forward model's offsets measured on its render at the scene file's values
        (reports.scene_fit.bias), None for a view without a render; measured once."""
        if self._bias is None:
            self._bias = [None] * len(self.views)
            if any(v.render is not None for v in self.views):
                nominal = self.table.nominal()
                cd = cd_geometry(self.applied(nominal).spec)
                for v, (view, pred) in enumerate(zip(self.views, self.predictions(nominal), strict=True)):
                    if view.render is not None and pred is not None:
                        self._bias[v], self.bias_notes[v] = self._measure_bias(view, view.render, pred, cd)
        return self._bias

    def _measure_bias(self, view: View, image: np.ndarray, pred: Prediction, cd) -> tuple[ViewBias | None, dict]:
        """The view's offsets on its render, where the render's own band edges are precise enough
        (scene_fit_bias.usable_render); else None, with why."""
        usable, note = usable_render(image, view.render_variance, pred.full(pred.on_cd) > 0.5)
        if not usable:
            return None, note
        render = render_photo(image)
        edges: dict[tuple, float] = {}
        for grid in view.grids:
            sampled = sampled_prediction(pred, grid)
            predicted = fringes.find_edges(grid, sampled, pred.orders)
            found = fringes.find_edges(grid, sampled, pred.orders, render.rgb, None, view.correlation_px)
            edges.update(band_offsets(found, predicted, grid))
        points = photo_rim_points(render, view.camera, self.spec)
        centre = view.camera.project(cd.center[None])[0]
        angles = np.arctan2(points[:, 1] - centre[1], points[:, 0] - centre[0])
        rim_angles, offsets = rim_offsets(angles, rim_residuals(view.camera, cd, points))
        return ViewBias(edges, rim_angles, offsets, centre), note

    def rim_only_residuals(self, values: np.ndarray) -> np.ndarray:
        """Every photo rim point's distance from the predicted rim (px; no prediction made: the
        rim depends on the CD's placement alone), less its render's offset where there is one."""
        cd = cd_geometry(self.applied(values).spec)
        biases = self.view_biases()
        return np.concatenate([np.zeros(0)] + [rim_residuals(v.camera, cd, v.rim_points)
                                               - (0.0 if b is None else b.rim(v.rim_points))
                                               for v, b in zip(self.views, biases, strict=True) if len(v.rim_points)])

    def residuals(self, values: np.ndarray, observed: ObservedEdges) -> np.ndarray:
        """Predicted minus observed position along each observed edge's profile (px; an edge
        the prediction does not show gets MISSING_EDGE_PX), then each photo rim point's
        distance from the predicted rim (rim_residuals)."""
        predicted = self.predicted_edges(values, observed.profiles())
        out = np.empty(observed.edge_count)
        for i, (key, edge, grid) in enumerate(zip(observed.keys, observed.edges, observed.grids, strict=True)):
            p = predicted.get(key)
            out[i] = MISSING_EDGE_PX if p is None else fringes.signed_offset(grid, edge, p)
        cd = cd_geometry(self.applied(values).spec)
        rims = [rim_residuals(self.views[v].camera, cd, points) for v, points in observed.rims]
        r = np.concatenate([out, *rims])
        return r if observed.bias is None else r - observed.bias
