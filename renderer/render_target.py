"""``workbench render --target report``: each region sampled until what the report measures there is good enough.

A fixed render spends its samples evenly, yet the report measures only a few things (issue
28): the CD's band edges (reports.fringes.band_edges), the walls' photometric scale (reports.compare.images)
and, for the page and the per-region test (reports.compare.regions), everything at a modest
noise. The targeted render is progressive: passes of ``PASS_SPP`` samples, each its own
seed, merged by their sample counts; between passes it measures its own noise from the
spread between them (the variance of the mean, as renderer.render.variance_path) in the
camera's image, per region (renderer.regions.region_masks, the report's masks), and stops
each region at its goal:

* everything: ``FLOOR_SPP`` samples (reports.compare.regions.TRUSTED_SPP: below it the
  passes' spread misses rare paths and the region test says so), in four passes (3 degrees of
  freedom per pixel for the variance, as renderer.render.MIN_PASSES);
* the walls: the relative standard deviation of the photometric scale, the median over
  wall pixels of photo / render, that the render's noise causes, at most ``WALL_SCALE_REL``
  (0.2 %). The sample median of N independent values has asymptotic variance 1 / (4 N f(m)^2)
  [David 2003], pi sigma^2 / (2 N) for Gaussian noise: with pixel i's relative
  noise s_i, var(scale) / scale^2 = (pi / 2) sum(s_i^2) / N^2;
* the CD: the band edges' position uncertainty at most ``EDGE_SIGMA_PX`` (0.1 px, a third
  of the report's edge rule, reports.fringes.band_edges.EDGE_SIGMA_MAX_PX). A level crossing at an
  edge of gradient dI/dx in noise sigma_I is located to sigma_x = sigma_I / |dI/dx|
  [Kakarala 1992]; the report's ramp fit, reports.fringes.band_edges, uses the same ratio. The
  edge finder reads the image smoothed along its profiles and fits its ramp over about a
  pixel either side; here the image and its variance are smoothed by a Gaussian of
  ``EDGE_SMOOTH_PX`` (the variance by the squared kernel, which is the variance of the
  smoothed image) and sigma_x is taken at the CD's edge pixels: inside its mask (eroded by
  ``CD_BORDER_PX``, so the rim and hole are not counted), where a channel's gradient is at
  least ``EDGE_GRADIENT_SHARE`` of the CD's bright level (its 99th percentile) per pixel.
  The goal holds for the ``EDGE_QUANTILE``th percentile of those pixels' sigma_x.

The frame renders until the floor and the walls are met (at most the preset's fixed spp);
then the CD alone renders as its own crop of the film (Mitsuba's film crop,
renderer.mitsuba_scene.cropped_sensor: the plan pixels the warp reads for the CD's image
pixels, plus ``CROP_MARGIN_PX``) until its edges are met (at most ``CAP_SPP``), in passes of
``weight`` times PASS_SPP samples (about ``CROP_PASS_SAMPLES`` samples a pass, so that a small
crop is not all per-pass overhead). Its pixels merge the frame's passes and the crop's,
weighted by their samples: with passes j of n_j samples and means m_j (N samples, J passes),
the mean is sum(n_j m_j) / N and the variance of that mean sum(n_j (m_j - m)^2) / ((J - 1) N),
the one-way analysis of variance's between-pass estimate of the per-sample variance
(E[sum n_j (m_j - m)^2] = (J - 1) sigma^2 [Scheffe 1959]) over N; with equal passes
it is renderer.render's s^2 / n.
After each check the next check comes where the noise, falling as 1 / sqrt(passes), is
predicted to meet the goal (growing at most ``MAX_GROWTH`` times), so few checks are made.

Every pass has its own deterministic seed (the frame's pass p: renderer.render.pass_seed(seed,
p); the crop's pass q: pass_seed(seed, CROP_SEED_OFFSET + q)), and the decisions depend only
on the merged sums, so the same request gives the same bytes. After each pass the sums, the
pass counts and the next check are saved atomically (``State``: the frame's sums while they
change, then the crop's alone, beside them); a killed render resumes
from them and decides as the uninterrupted one did. The sidecar's ``target`` records per
region the spp used and the noise reached, and each check.
"""

from __future__ import annotations

import json
import math
import zipfile
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from renderer.camera import CameraModel, PinholePlan
from renderer.regions import WALL_REGIONS
from workbench.core.files import atomic_write_npz

TARGETS = ("report",)
EDGE_SIGMA_PX = 0.1  # a third of reports.fringes.band_edges.EDGE_SIGMA_MAX_PX (0.35), issue 28
WALL_SCALE_REL = 0.002  # the walls' photometric scale to 0.2 %, issue 28
FLOOR_SPP = 64  # reports.compare.regions.TRUSTED_SPP (tests/renderer/test_render_target.py holds them equal)
PASS_SPP = 16  # the floor in MIN_PASSES = 4 passes: 3 degrees of freedom per pixel for the variance
EDGE_SMOOTH_PX = 1.0
EDGE_GRADIENT_SHARE = 0.1
EDGE_QUANTILE = 90.0
CD_BORDER_PX = 3  # the region test's 2 px border (reports.compare.regions.BORDER_PX) and the smoothing's reach
WALL_BORDER_PX = 1  # as reports.compare.images.photometric_scale erodes the walls
CROP_MARGIN_PX = 2  # bilinear warp: an image pixel reads the plan pixels around it
MAX_GROWTH = 4.0
# the CD's samples at most (frame and crop together): 4 and 2 times the presets' fixed spp
CAP_SPP = {"draft": 1024, "paper": 4096}
CROP_PASS_SAMPLES = 2**18  # samples a crop pass aims at: its spp a power-of-two multiple of PASS_SPP, at most 16
CROP_SEED_OFFSET = 50_000  # the crop's passes' seed indices; the frame's stay far below it

RenderPasses = Callable[[str, range], Iterator[np.ndarray]]  # ("frame" | "crop", pass indices) -> pass images


@dataclass(frozen=True)
class Window:
    """A window of the pinhole plan's film: its offset (x, y) and size (width, height) in plan pixels."""

    x: int
    y: int
    width: int
    height: int

    @property
    def slices(self) -> tuple[slice, slice]:
        return slice(self.y, self.y + self.height), slice(self.x, self.x + self.width)

    def to_json(self) -> list[int]:
        return [self.x, self.y, self.width, self.height]


def target_settings(preset: str, frame_cap_spp: int) -> dict:
    """What a targeted render is asked for (part of its request key): the goals, the pass size and the caps."""
    return {"target": "report", "edge_sigma_px": EDGE_SIGMA_PX, "wall_scale_rel": WALL_SCALE_REL, "floor_spp": FLOOR_SPP,
            "pass_spp": PASS_SPP, "frame_cap_spp": max(frame_cap_spp, FLOOR_SPP), "cd_cap_spp": CAP_SPP[preset],
            "edge_smooth_px": EDGE_SMOOTH_PX, "edge_gradient_share": EDGE_GRADIENT_SHARE, "edge_quantile": EDGE_QUANTILE,
            "cd_border_px": CD_BORDER_PX, "crop_margin_px": CROP_MARGIN_PX, "max_growth": MAX_GROWTH,
            "crop_pass_samples": CROP_PASS_SAMPLES}


# ---------------------------------------------------------------- what the report measures


def _eroded(mask: np.ndarray, border: int) -> np.ndarray:
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * border + 1, 2 * border + 1), np.uint8)) > 0


def edge_sigma(mean: np.ndarray, var: np.ndarray, cd: np.ndarray) -> tuple[float, int]:
    """The CD's band edges' position uncertainty (module docstring): the EDGE_QUANTILE-th
    percentile of sigma_I / |grad I| over the CD's edge pixels, in image pixels, and how many
    (pixel, channel) pairs it was taken over; (nan, 0) where the CD shows no edge."""
    inner = _eroded(cd, CD_BORDER_PX)
    if not inner.any():
        return float("nan"), 0
    kernel = cv2.getGaussianKernel(2 * math.ceil(3 * EDGE_SMOOTH_PX) + 1, EDGE_SMOOTH_PX)
    sigmas = []
    for c in range(3):
        level = cv2.sepFilter2D(np.ascontiguousarray(mean[..., c], np.float64), -1, kernel, kernel)
        noise = cv2.sepFilter2D(np.ascontiguousarray(var[..., c], np.float64), -1, kernel**2, kernel**2)
        gy, gx = np.gradient(level)
        slope = np.hypot(gx, gy)
        edge = inner & (slope >= EDGE_GRADIENT_SHARE * max(float(np.percentile(level[inner], 99)), 0.0)) & (slope > 0)
        sigmas.append(np.sqrt(np.maximum(noise[edge], 0.0)) / slope[edge])
    values = np.concatenate(sigmas)
    return (float(np.percentile(values, EDGE_QUANTILE)), int(len(values))) if len(values) else (float("nan"), 0)


def wall_scale_noise(sum_mean: np.ndarray, sum_var: np.ndarray, masks: dict[str, np.ndarray]) -> tuple[float, int]:
    """The relative std of the walls' photometric scale from the render's noise (module
    docstring), from the channel sums' mean and variance; (nan, 0) without wall pixels."""
    walls = np.zeros(sum_mean.shape, bool)
    for name in WALL_REGIONS:
        if name in masks:
            walls |= masks[name]
    use = _eroded(walls, WALL_BORDER_PX) & (sum_mean > 0)
    n = int(use.sum())
    if n == 0:
        return float("nan"), 0
    return float(math.sqrt(math.pi / 2 * float(np.sum(sum_var[use] / sum_mean[use] ** 2))) / n), n


def region_noise(mean: np.ndarray, var: np.ndarray, mask: np.ndarray) -> float:
    """The relative std of a region's mean (channel sums), as the region test's render term
    (reports.compare.regions: the sum of the pixels' variances over N^2)."""
    n = int(mask.sum())
    total = float(mean[..., 3][mask].sum()) if n else 0.0
    return math.sqrt(float(var[..., 3][mask].sum())) / total if total > 0 else float("nan")


# ---------------------------------------------------------------- the CD's crop


def crop_window(cd: np.ndarray, camera: CameraModel, plan: PinholePlan) -> Window | None:
    """The plan pixels the warp reads for the CD's image pixels (and CROP_MARGIN_PX around):
    the warp of the plan's own pixel coordinates gives, per image pixel, where it reads
    (bilinear interpolation of a linear function is exact), whatever the lens model."""
    if not cd.any():
        return None
    ys, xs = np.mgrid[0:plan.height, 0:plan.width].astype(np.float32)
    at_x, at_y = camera.warp(xs, plan), camera.warp(ys, plan)
    x0 = max(int(math.floor(at_x[cd].min())) - CROP_MARGIN_PX, 0)
    y0 = max(int(math.floor(at_y[cd].min())) - CROP_MARGIN_PX, 0)
    x1 = min(int(math.ceil(at_x[cd].max())) + CROP_MARGIN_PX, plan.width - 1)
    y1 = min(int(math.ceil(at_y[cd].max())) + CROP_MARGIN_PX, plan.height - 1)
    return Window(x0, y0, x1 - x0 + 1, y1 - y0 + 1)


# ---------------------------------------------------------------- the sums, saved after each pass


@dataclass
class State:
    """The running sums of the frame's and the crop's passes (channels R, G, B and their sum),
    the passes done and the pass count of the next check of each."""

    key: str
    frame_total: np.ndarray | None = None
    frame_sq: np.ndarray | None = None
    frame_done: int = 0
    frame_goal: int = FLOOR_SPP // PASS_SPP
    crop_total: np.ndarray | None = None
    crop_sq: np.ndarray | None = None
    crop_done: int = 0
    crop_goal: int = -1  # -1: the frame's passes are not finished
    complete: bool = False  # every region's last check said stop
    checks: list[dict] = field(default_factory=list)

    def add(self, kind: str, image: np.ndarray) -> None:
        four = np.concatenate([image, image.sum(axis=2, keepdims=True)], axis=2).astype(np.float64)
        if kind == "frame":
            self.frame_total = four if self.frame_total is None else self.frame_total + four
            self.frame_sq = four**2 if self.frame_sq is None else self.frame_sq + four**2
            self.frame_done += 1
        else:
            self.crop_total = four if self.crop_total is None else self.crop_total + four
            self.crop_sq = four**2 if self.crop_sq is None else self.crop_sq + four**2
            self.crop_done += 1

    def merged(self, window: Window | None, weight: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The plan image's mean, the variance of that mean (both (H, W, 4)) and each pixel's samples in
        units of PASS_SPP (H, W); a crop pass holds ``weight`` such units (module docstring)."""
        assert self.frame_total is not None and self.frame_sq is not None
        total, sq = self.frame_total.copy(), self.frame_sq.copy()
        units = np.full(total.shape[:2], float(self.frame_done))
        passes = np.full(total.shape[:2], float(self.frame_done))
        if window is not None and self.crop_done:
            assert self.crop_total is not None and self.crop_sq is not None
            total[window.slices] += weight * self.crop_total
            sq[window.slices] += weight * self.crop_sq
            units[window.slices] += weight * self.crop_done
            passes[window.slices] += self.crop_done
        n, j = units[..., None], passes[..., None]
        mean = total / n
        var = np.maximum(sq - n * mean**2, 0.0) / np.maximum(j - 1, 1) / n
        return mean, var, units

    def save(self, path: Path) -> None:
        """Atomically: the frame's sums in ``path`` while they change (and once more when its passes end),
        then only the crop's in crop_path(path) (each with the counts and checks): the frame's sums are
        large and fixed by then, the crop's passes many."""
        counts = np.array([self.frame_done, self.frame_goal, self.crop_done, self.crop_goal, int(self.complete)])
        common = {"key": np.array(self.key), "counts": counts, "checks": np.array(json.dumps(self.checks))}
        if self.crop_done == 0:
            atomic_write_npz(path, **common, frame_total=self.frame_total, frame_sq=self.frame_sq)
        else:
            atomic_write_npz(crop_path(path), **common, crop_total=self.crop_total, crop_sq=self.crop_sq)

    @classmethod
    def load(cls, path: Path, key: str) -> State:
        """The saved state of this request at ``path`` (and crop_path(path)), or a fresh one."""
        frame = _read_npz(path, key, ("frame_total", "frame_sq"))
        if frame is None:
            return cls(key)
        state = cls(key, frame["frame_total"], frame["frame_sq"], *frame["counts"][:2])
        crop = _read_npz(crop_path(path), key, ("crop_total", "crop_sq"))
        if crop is not None and crop["counts"][0] == state.frame_done and frame["counts"][3] >= 0:
            frame = crop
            state.crop_total, state.crop_sq = crop["crop_total"], crop["crop_sq"]
        state.crop_done, state.crop_goal, complete = frame["counts"][2:]
        state.complete, state.checks = bool(complete), frame["checks"]
        return state

    @property
    def passes(self) -> int:
        return self.frame_done + self.crop_done


def crop_path(path: Path) -> Path:
    """Where a targeted render's crop sums are saved beside its frame's (State.save)."""
    return path.with_name(path.name.removesuffix(".npz") + ".crop.npz")




# What reading a damaged .npz raises: a truncated or overwritten archive, a damaged member.
DAMAGED_NPZ = (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile, zlib.error)


def _read_npz(path: Path, key: str, names: tuple[str, ...]) -> dict[str, Any] | None:
    """A saved part of this request's state: ``names``' arrays, the counts (ints) and checks; None if absent or not ours."""
    try:
        with np.load(path) as d:
            if str(d["key"]) != key:
                return None
            return {n: d[n] for n in names} | {"counts": [int(v) for v in d["counts"]],
                                               "checks": json.loads(str(d["checks"]))}
    except DAMAGED_NPZ:
        return None


def discard_damaged_checkpoints(partial: Path) -> list[Path]:
    """Remove the render's checkpoints (``partial`` and its crop sums) that cannot be read whole, and
    name them: a damaged checkpoint is only lost work, and left in place it would be read on every rerun."""
    damaged = []
    for path in (partial, crop_path(partial)):
        if not path.is_file():
            continue
        try:
            with np.load(path) as d:
                for name in d.files:
                    d[name]
        except DAMAGED_NPZ:
            path.unlink(missing_ok=True)
            damaged.append(path)
    return damaged


# ---------------------------------------------------------------- the passes, and when to stop


@dataclass(frozen=True)
class Target:
    """What the passes are checked against: the camera and its plan, the report's region
    masks (image pixels), the CD's crop window and the caps (in passes)."""

    camera: CameraModel
    plan: PinholePlan
    masks: dict[str, np.ndarray]
    window: Window | None
    frame_cap: int  # in passes of PASS_SPP
    cd_cap: int  # in units of PASS_SPP samples, frame and crop together
    weight: int  # a crop pass's samples in units of PASS_SPP

    @classmethod
    def build(cls, camera: CameraModel, plan: PinholePlan, masks: dict[str, np.ndarray], settings: dict) -> Target:
        window = crop_window(masks["cd"], camera, plan) if "cd" in masks else None
        area = window.width * window.height if window is not None else 1
        weight = int(2 ** round(math.log2(max(CROP_PASS_SAMPLES / (area * PASS_SPP), 1.0))))
        return cls(camera, plan, masks, window, settings["frame_cap_spp"] // PASS_SPP,
                   max(settings["cd_cap_spp"] // PASS_SPP, settings["frame_cap_spp"] // PASS_SPP), min(weight, 16))

    @property
    def crop_pass_spp(self) -> int:
        return self.weight * PASS_SPP


def warped(state: State, target: Target) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The merged mean, its variance (both (h, w, 4) in the camera's image) and each image pixel's passes."""
    mean, var, count = state.merged(target.window, target.weight)
    return (target.camera.warp(mean, target.plan), np.maximum(target.camera.warp(var, target.plan), 0.0),
            target.camera.warp(count, target.plan))


def measure(state: State, target: Target) -> dict:
    """The noise of what the report measures, now: the CD's edges and the walls' scale."""
    mean, var, _count = warped(state, target)
    cd = target.masks.get("cd")
    sigma, edges = edge_sigma(mean[..., :3], var[..., :3], cd) if cd is not None else (float("nan"), 0)
    scale, walls = wall_scale_noise(mean[..., 3], var[..., 3], target.masks)
    return {"edge_sigma_px": sigma, "edge_pixels": edges, "wall_scale_rel": scale, "wall_pixels": walls}


def _grown(done: int, noise: float, goal: float, cap: int) -> int:
    """The pass count where ``noise`` (measured at ``done`` passes, falling as 1 / sqrt(passes))
    meets ``goal``: at least one more pass, at most MAX_GROWTH times as many, and ``cap``;
    ``done`` itself where it is met (or nothing is measured) or the cap is reached."""
    if not math.isfinite(noise) or noise <= goal or done >= cap:
        return done
    want = math.ceil(done * (noise / goal) ** 2)
    return min(cap, max(done + 1, min(want, math.floor(done * MAX_GROWTH))))


def _next_goal(kind: str, state: State, stats: dict, target: Target) -> int:
    """The pass count of ``kind``'s next check (its passes done: stop)."""
    if kind == "frame":
        return _grown(state.frame_done, stats["wall_scale_rel"], WALL_SCALE_REL, target.frame_cap)
    units = _grown(state.frame_done + target.weight * state.crop_done, stats["edge_sigma_px"], EDGE_SIGMA_PX, target.cd_cap)
    return math.ceil((units - state.frame_done) / target.weight)


def _phase(kind: str, state: State, target: Target, render_passes: RenderPasses, save: Callable[[], None],
           on_pass: Callable[[], None]) -> None:
    """Render ``kind``'s passes (the frame's or the crop's) check by check until its goal is met."""
    while True:
        done, goal = (state.frame_done, state.frame_goal) if kind == "frame" else (state.crop_done, state.crop_goal)
        for image in render_passes(kind, range(done, goal)):
            state.add(kind, image)
            save()
            on_pass()
        stats = measure(state, target)
        new_goal = _next_goal(kind, state, stats, target)
        state.checks.append({"pass_kind": kind, "frame_passes": state.frame_done, "crop_passes": state.crop_done} | stats)
        finished = new_goal <= (state.frame_done if kind == "frame" else state.crop_done)
        if kind == "frame":
            crop_goal = _next_goal("crop", state, stats, target) if target.window is not None else 0
            state.frame_goal, state.crop_goal = (state.frame_done, crop_goal) if finished else (new_goal, -1)
            state.complete = finished and crop_goal == 0
        else:
            state.crop_goal, state.complete = (state.crop_done, True) if finished else (new_goal, False)
        save()
        if finished:
            return


def sample(state: State, target: Target, render_passes: RenderPasses, save: Callable[[], None],
           on_pass: Callable[[], None]) -> None:
    """The frame's passes until the floor and the walls are met, then the CD's crop until its edges are
    (the frame's last check decides the crop's first)."""
    if state.crop_goal < 0:
        _phase("frame", state, target, render_passes, save, on_pass)
    if not state.complete:
        _phase("crop", state, target, render_passes, save, on_pass)


def record(state: State, target: Target, settings: dict) -> dict:
    """The sidecar's ``target``: per region the spp used (min, max over its pixels) and the noise
    reached (its mean's relative std; the CD's edges, the walls' scale), and every check."""
    mean, var, count = warped(state, target)
    last = measure(state, target)
    regions = {}
    for name, mask in sorted(target.masks.items()):
        if not mask.any():
            continue
        spp = count[mask] * PASS_SPP
        regions[name] = {"pixels": int(mask.sum()), "spp": [int(round(spp.min())), int(round(spp.max()))],
                         "mean_relative_std": region_noise(mean, var, mask)}
    if "cd" in regions:
        regions["cd"] |= {"edge_sigma_px": last["edge_sigma_px"], "edge_pixels": last["edge_pixels"],
                          "goal_edge_sigma_px": EDGE_SIGMA_PX, "met": bool(last["edge_pixels"] == 0
                                                                          or last["edge_sigma_px"] <= EDGE_SIGMA_PX)}
    walls = {"scale_relative_std": last["wall_scale_rel"], "goal": WALL_SCALE_REL,
             "met": bool(not math.isfinite(last["wall_scale_rel"]) or last["wall_scale_rel"] <= WALL_SCALE_REL)}
    return {"settings": settings, "crop": target.window.to_json() if target.window else None,
            "frame_spp": state.frame_done * PASS_SPP, "crop_spp": state.crop_done * target.crop_pass_spp,
            "crop_pass_spp": target.crop_pass_spp, "frame_passes": state.frame_done, "crop_passes": state.crop_done,
            "regions": regions, "walls": walls, "checks": state.checks}
