"""The simulation planner: what a scene needs simulated, worked out before anything runs.

``plan_scene(spec)`` reads a scene and decides, for each diffractive element (CD,
grating plate), which efficiency tables a render of it needs and over which part of
their domain, and for each glass object whether its dispersion matters; ``workbench
plan SCENE`` prints it (``--json`` as one object).

How the incidence domain is found. The renderer looks a table up only at incidence
directions that some camera ray can be diffracted from: a camera ray that meets the
element at a point p leaves it along omega_o, and the BWDF asks, for every kept order
(m, n) and wavelength lambda, for the efficiency of the incident direction that order
sends to omega_o. With the tangential wave vectors over k0 (the grating equation,
Lange et al. 2021 Eq. 2, with the sign of workbench.core.conventions; tangential k is
kept across the CD's flat polycarbonate top, so the camera's side in air gives it):

    k_inc = n_cam omega_o,t - ORDER_SIGN (m lambda / Lambda_x, n lambda / Lambda_y),

and the table's angles are sin(theta) = |k_inc| / n_light, phi = atan2(k_inc,y, k_inc,x)
(renderer.bwdf.BWDF._incident), folded into the stored azimuth range by the cell's
mirror symmetry. The planner casts one ray per camera pixel (every k-th pixel on images
wider than PLAN_RAYS_ACROSS; no occlusion: a superset of what the camera sees),
evaluates this for every order and for wavelengths 5 nm apart over the camera's range,
and marks the grid nodes of the table that bilinear interpolation then reads (the four
around each direction; neighbouring rays and 5 nm steps move the direction far less
than a grid step, so no margin is needed), per
wavelength chunk of the table: the renderer interpolates linearly in wavelength, so table
wavelength lambda_i serves every wavelength between its neighbours lambda_i-1 and
lambda_i+1, and only the directions those wavelengths reach are needed at lambda_i. Light arriving after a diffuse
bounce comes from every lit surface of the box, so no direction is left out for want of
direct light; the plan reports what share of the needed directions sees the light
directly. A grating with one groove direction, seen by one camera, needs a thin set of
streaks; a CD's radial grooves turn every azimuth of the grating frame into a needed one.

What a render skips besides: no RCWA at all without a diffractive element in view; R
only over an opaque substrate; the side a camera cannot see; dispersion for glass the
camera cannot see.

The estimated time of a table is measured here: a short sweep at the table's orders,
timed, scaled to the table's directions and wavelengths on this machine's cores.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from renderer.scene import CD_TOP_THICKNESS_M, SceneSpec
from workbench.core.conventions import ORDER_SIGN

PLAN_WAVELENGTH_STEP_NM = 5.0  # wavelengths sampled for the domain; the tables' own steps are 10 nm or more
NODE_MARGIN = 0  # extra grid nodes around a needed cell: none, since one ray per pixel is far denser than any table grid
COST_SAMPLE_DIRECTIONS = 16  # directions timed for the cost model
PLAN_RAYS_ACROSS = 400  # rays across the image: neighbours 0.1 deg apart for a 40 deg view, far below any table step (2 deg)


@dataclass
class ElementPlan:
    """What one diffractive element needs (angles in degrees, wavelengths in nm)."""

    key: str
    structure: str
    visible_pixels: int
    camera_side: str  # "above" (the superstrate's side), "below" or "both"
    see_through: bool
    tables: list[str]
    orders_needed: list[tuple[int, int]]
    orders_kept: list[tuple[int, int]]
    wavelength_range_nm: tuple[float, float]
    symmetry: str
    grid_theta_deg: list[float]
    grid_phi_deg: list[float]
    directions_needed: int
    directions_total: int
    theta_range_deg: tuple[float, float] | None
    phi_range_deg: tuple[float, float] | None
    direct_light_share: float
    seconds_whole: float
    seconds_planned: float
    megabytes_whole: float
    fill_orders: tuple[int, ...] = ()
    fill_error: dict[str, float] = field(default_factory=dict)  # |R_fill - R| over the cost sample: max, median
    notes: list[str] = field(default_factory=list)
    mask: np.ndarray | None = field(default=None, repr=False)

    @property
    def fraction(self) -> float:
        return self.directions_needed / self.directions_total if self.directions_total else 0.0

    def node_plan(self):
        """The rcwa.table.NodePlan a render builds this element's table with: out of view,
        every node is a fill node (paths can still reach the element after a bounce)."""
        from rcwa.table import NodePlan

        return None if self.mask is None else NodePlan(self.mask, self.fill_orders)

    def to_json(self) -> dict[str, Any]:
        data = {k: v for k, v in asdict(self).items() if k != "mask"}
        data["fraction"] = self.fraction
        return data


@dataclass
class GlassPlan:
    key: str
    visible_pixels: int
    dispersion_in_scene: bool
    dispersion_needed: bool


@dataclass
class Plan:
    scene: str
    camera_wavelength_range_nm: tuple[float, float]
    elements: list[ElementPlan]
    glass: list[GlassPlan]
    rcwa_needed: bool
    seconds: float

    def to_json(self) -> dict[str, Any]:
        return {"scene": self.scene, "camera_wavelength_range_nm": list(self.camera_wavelength_range_nm),
                "rcwa_needed": self.rcwa_needed, "elements": [e.to_json() for e in self.elements],
                "glass": [asdict(g) for g in self.glass], "planning_seconds": self.seconds}


# ---------------------------------------------------------------- geometry


def camera_rays(spec: SceneSpec, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """The camera centre (3,) and a unit ray direction per pixel (every ``step``-th pixel
    in each direction), world frame."""
    cam = spec.camera.model
    v, u = np.mgrid[0:cam.height:step, 0:cam.width:step]
    return cam.pixel_rays(np.stack([u.ravel(), v.ravel()], axis=1).astype(float))


def ray_step(spec: SceneSpec) -> int:
    """The pixel step of the planner's rays: at most PLAN_RAYS_ACROSS rays across the image."""
    return max(1, math.ceil(spec.camera.model.width / PLAN_RAYS_ACROSS))


def plane_hits(origin: np.ndarray, rays: np.ndarray, center: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points where the rays meet the plane (through ``center``, ``normal``), and which rays do."""
    denom = rays @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((center - origin) @ normal) / denom
    ok = np.isfinite(t) & (t > 0)
    return origin + rays * np.where(ok, t, 0.0)[:, None], ok


def _frame(normal, rotation_deg: float) -> np.ndarray:
    from renderer.build import frame_to

    return frame_to(normal, rotation_deg)


def element_hits(spec: SceneSpec, origin: np.ndarray, rays: np.ndarray) -> list[dict[str, Any]]:
    """For each CD and grating: the hit points the camera sees, the grating axis there and the normal."""
    out = []
    for i, cd in enumerate(spec.cds):
        frame = _frame(cd.normal, cd.rotation_deg)
        normal = frame[:, 2]
        center = np.asarray(cd.center, float)
        points, ok = plane_hits(origin, rays, center, normal)
        radius = np.linalg.norm(points - center, axis=1)
        ok &= (radius >= cd.inner_radius) & (radius <= cd.outer_radius)
        radial = (points[ok] - center) / np.maximum(radius[ok, None], 1e-12)
        out.append({"key": f"cd[{i}]", "element": cd, "points": points[ok], "axis": radial, "normal": normal,
                    "top": cd.top_surface})
    for i, g in enumerate(spec.gratings):
        frame = _frame(g.normal, g.rotation_deg)
        center = np.asarray(g.center, float)
        points, ok = plane_hits(origin, rays, center, frame[:, 2])
        local = (points - center) @ frame
        ok &= (np.abs(local[:, 0]) <= g.size[0] / 2) & (np.abs(local[:, 1]) <= g.size[1] / 2)
        out.append({"key": f"grating[{i}]", "element": g, "points": points[ok],
                    "axis": np.repeat(frame[:, 0][None], int(ok.sum()), axis=0), "normal": frame[:, 2], "top": False})
    return out


def _glass_visible(spec: SceneSpec, origin: np.ndarray, rays: np.ndarray) -> list[int]:
    """Pixels whose ray meets each glass object's bounding sphere (a superset of what the camera sees)."""
    counts = []
    for g in spec.glass:
        radius = g.size if g.shape == "sphere" else g.size * math.sqrt(3) / 2
        rel = np.asarray(g.center, float) - origin
        along = rays @ rel
        miss2 = rel @ rel - along**2
        counts.append(int(np.count_nonzero((along > 0) & (miss2 <= radius**2))))
    return counts


# ---------------------------------------------------------------- the domain


def fold_azimuths(phi_deg: np.ndarray, mirror_x: bool, mirror_y: bool, diagonal: bool = False) -> np.ndarray:
    """Azimuths folded into a table's stored range (rcwa.symmetry.fold_azimuths, the rule
    rcwa.table.Table.fold_azimuth applies); the nodes a lookup reads do not depend on the
    order flips or the swap."""
    from rcwa import symmetry

    return symmetry.fold_azimuths(phi_deg, mirror_x, mirror_y, diagonal)[0]


def _mark(mask: np.ndarray, grid_theta: np.ndarray, grid_phi: np.ndarray, theta: np.ndarray, phi: np.ndarray) -> None:
    """Mark the grid nodes bilinear interpolation reads at (theta, phi), with the margin."""
    it = np.clip(np.searchsorted(grid_theta, theta, side="right") - 1, 0, len(grid_theta) - 1)
    ip = np.clip(np.searchsorted(grid_phi, phi, side="right") - 1, 0, len(grid_phi) - 1)
    for dt in range(-NODE_MARGIN, 2 + NODE_MARGIN):
        for dp in range(-NODE_MARGIN, 2 + NODE_MARGIN):
            mask[np.clip(it + dt, 0, len(grid_theta) - 1), np.clip(ip + dp, 0, len(grid_phi) - 1)] = True


def incident_directions(omega_t: np.ndarray, m: int, n: int, lam: float, period: tuple[float, ...],
                         n_cam: float, n_light: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Table (theta, phi) in degrees of order (m, n)'s incident wave, and which exist (propagate)."""
    kx = n_cam * omega_t[:, 0] - ORDER_SIGN * m * lam / (1000.0 * period[0])
    ky = n_cam * omega_t[:, 1] - (ORDER_SIGN * n * lam / (1000.0 * period[1]) if len(period) > 1 else 0.0)
    s = np.hypot(kx, ky) / n_light
    ok = s < 1.0
    theta = np.degrees(np.arcsin(np.minimum(s, 1.0)))
    phi = np.degrees(np.arctan2(ky, kx))
    return theta, phi, ok


def _light_directions(spec: SceneSpec) -> tuple[np.ndarray, np.ndarray]:
    """The ceiling light's rectangle: centre (3,) and half-extents along world x and z."""
    return np.asarray(spec.light.center, float), np.asarray(spec.light.size, float) / 2


def hits_light(points: np.ndarray, directions: np.ndarray, spec: SceneSpec) -> np.ndarray:
    """Whether rays from ``points`` along ``directions`` (world) meet the light's rectangle (facing down)."""
    center, half = _light_directions(spec)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (center[1] - points[:, 1]) / directions[:, 1]
    hit = points + directions * np.where(np.isfinite(t), t, 0.0)[:, None]
    return (t > 0) & (np.abs(hit[:, 0] - center[0]) <= half[0]) & (np.abs(hit[:, 2] - center[2]) <= half[1])


# ---------------------------------------------------------------- the plan


def _table_settings(element, structure, where: str, scene_file: str | None):
    from renderer.build import scene_settings_for

    options = {k: v for k, v in dict(element.table).items() if k != "path"}
    preset = options.pop("preset", "draft")
    return scene_settings_for(structure, preset, options, where, scene_file)


def _indices(structure, wavelengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n1 = np.sqrt(np.asarray(structure.superstrate.epsilon(wavelengths), dtype=complex)).real
    n3 = np.sqrt(np.asarray(structure.substrate.epsilon(wavelengths), dtype=complex)).real
    return n1, n3


def _cost_sample(structure, settings, fill_orders: tuple[int, ...]) -> tuple[float, float, dict[str, float]]:
    """Measured on COST_SAMPLE_DIRECTIONS directions at the middle wavelength: seconds per
    direction with the table's orders and with the fill's, and the fill's error there
    (|R_fill - R| over the kept orders: max and median)."""
    from rcwa.sweep import sweep_directions

    wl = settings.wavelengths_nm[len(settings.wavelengths_nm) // 2]
    rng = np.random.default_rng(0)
    theta = rng.uniform(0.0, 80.0, COST_SAMPLE_DIRECTIONS)
    phi = rng.uniform(0.0, 90.0, COST_SAMPLE_DIRECTIONS)
    sweep_directions(structure, wl, theta[:2], phi[:2], settings.orders, settings.keep, threads=1)  # warm up
    start = time.perf_counter()
    exact = sweep_directions(structure, wl, theta, phi, settings.orders, settings.keep, threads=1)
    middle = time.perf_counter()
    fill = sweep_directions(structure, wl, theta, phi, fill_orders, settings.keep, threads=1)
    end = time.perf_counter()
    error = np.abs(fill.R - exact.R)
    return ((middle - start) / COST_SAMPLE_DIRECTIONS, (end - middle) / COST_SAMPLE_DIRECTIONS,
            {"max": float(error.max()), "median": float(np.median(error.max(axis=(1, 2))))})


def plan_element(spec: SceneSpec, hit: dict[str, Any], origin: np.ndarray, camera_range: tuple[float, float],
                 *, measure_cost: bool = True) -> ElementPlan:
    import rcwa
    from rcwa.table import _kept_indices, _transmits, table_symmetry

    element = hit["element"]
    structure = rcwa.load_structure(element.structure)
    settings = _table_settings(element, structure, hit["key"], spec.source)
    sym = table_symmetry(structure, settings.orders, settings.keep, settings.use_symmetry)
    see_through = _transmits(structure, settings) and not settings.reflection_only
    grid_theta, grid_phi = np.asarray(settings.theta_deg), np.asarray(settings.phi_deg)
    ms, ns = _kept_indices(settings.keep)
    kept = [(int(m), int(n)) for m, n in zip(ms, ns, strict=True)]
    points, axis, normal = hit["points"], hit["axis"], hit["normal"]
    omega = origin - points
    omega /= np.maximum(np.linalg.norm(omega, axis=1, keepdims=True), 1e-300)
    side = omega @ normal
    ey = np.cross(normal, axis)
    omega_t = np.stack([np.einsum("ij,ij->i", omega, axis), np.einsum("ij,ij->i", omega, ey)], axis=1)
    lo, hi = max(camera_range[0], min(settings.wavelengths_nm)), min(camera_range[1], max(settings.wavelengths_nm))
    table_wl = np.asarray(settings.wavelengths_nm)
    samples = _chunk_samples(table_wl, lo, hi)
    masks = {name: np.zeros((len(table_wl), len(grid_theta), len(grid_phi)), bool) for name in ("R", "T", "R_below", "T_below")}
    needed_orders: set[tuple[int, int]] = set()
    direct = total = 0
    sides = {"above": side > 0, "below": side < 0}
    for side_name, on_side in sides.items():
        if not on_side.any() or (side_name == "below" and not see_through):
            continue
        channels = [("R" if side_name == "above" else "R_below", False)]
        if see_through:
            channels.append(("T_below" if side_name == "above" else "T", True))
        for table_name, transmitted in channels:
            for chunk, lam in samples:
                n1, n3 = _indices(structure, np.array([lam]))
                # omega_t is the camera's direction in air; behind a flat top the BWDF's n_pc sin(theta_pc) is sin(theta_air)
                n_cam = 1.0 if hit["top"] else (n1[0] if side_name == "above" else n3[0])
                n_side = n1[0] if side_name == "above" else n3[0]  # the table's angles are in this medium
                n_light = (n3[0] if side_name == "above" else n1[0]) if transmitted else n_side
                for m, n in kept:
                    theta, phi, ok = incident_directions(omega_t[on_side], m, n, lam, structure.period, n_cam, n_light)
                    if not ok.any():
                        continue
                    needed_orders.add((m, n))
                    folded = fold_azimuths(phi[ok], sym.x, sym.y, sym.diagonal)
                    _mark(masks[table_name][chunk], grid_theta, grid_phi, theta[ok], folded)
                    src = source_rays(theta[ok], phi[ok], axis[on_side][ok], ey[on_side][ok], normal,
                                       above=(side_name == "above") != transmitted)
                    direct += int(np.count_nonzero(hits_light(points[on_side][ok], src, spec)))
                    total += int(ok.sum())
    used = [name for name, mk in masks.items() if mk.any()]
    union = np.zeros_like(masks["R"])
    for name in used:
        union |= masks[name]
    seen = np.any(union, axis=0)  # (theta, phi) nodes some wavelength needs
    theta_range = (float(grid_theta[seen.any(axis=1)].min()), float(grid_theta[seen.any(axis=1)].max())) if seen.any() else None
    phi_range = (float(grid_phi[seen.any(axis=0)].min()), float(grid_phi[seen.any(axis=0)].max())) if seen.any() else None
    nodes_whole = len(grid_theta) * len(grid_phi) * len(table_wl)
    whole_tables = ["R", "T"] if see_through else ["R"]
    if settings.both_sides or see_through:
        whole_tables += [name + "_below" for name in whole_tables]
    fill_orders = tuple(settings.keep)  # the nodes no camera ray reads: only the kept orders retained (rcwa.table.NodePlan)
    per_dir, per_fill, fill_error = (_cost_sample(structure, settings, fill_orders) if measure_cost and samples
                                     else (0.0, 0.0, {}))
    cores = os.cpu_count() or 1
    nwl = 1  # the node counts below include the wavelength axis
    sides_whole = 2 if (settings.both_sides or see_through) else 1
    needed_above = int((masks["R"] | masks["T"]).sum())
    needed_below = int((masks["R_below"] | masks["T_below"]).sum())
    bytes_whole = len(whole_tables) * nodes_whole * len(kept) * len(settings_pol(settings)) * 4
    notes = []
    if not samples:
        notes.append("the table's wavelengths miss the camera's range: nothing to look up")
    if not len(points):
        notes.append("the camera does not see this element: nothing to simulate")
    if hit["top"]:
        notes.append(f"seen through a {CD_TOP_THICKNESS_M * 1e3:g} mm flat polycarbonate top: tangential k is kept across it")
    return ElementPlan(
        key=hit["key"], structure=structure.name, visible_pixels=int(len(points)),
        camera_side=_side_name(side), see_through=bool(see_through), tables=used, orders_needed=sorted(needed_orders),
        orders_kept=kept, wavelength_range_nm=(float(lo), float(hi)),
        symmetry=f"{sym.describe()}, azimuths stored {sym.azimuth_range()[0]:g}-{sym.azimuth_range()[1]:g} deg",
        grid_theta_deg=[float(x) for x in grid_theta], grid_phi_deg=[float(x) for x in grid_phi],
        directions_needed=int(union.sum()), directions_total=nodes_whole, theta_range_deg=theta_range,
        phi_range_deg=phi_range, direct_light_share=direct / total if total else 0.0,
        seconds_whole=per_dir * nodes_whole * nwl * sides_whole / cores,
        seconds_planned=(per_dir * (needed_above + needed_below)
                         + per_fill * (nodes_whole * sides_whole - needed_above - needed_below)) * nwl / cores,
        megabytes_whole=bytes_whole / 1e6, fill_orders=fill_orders, fill_error=fill_error, notes=notes, mask=union,
    )


def _chunk_samples(table_wl: np.ndarray, lo: float, hi: float) -> list[tuple[int, float]]:
    """(table chunk, wavelength) pairs: the wavelengths, 5 nm apart within the camera's range
    [lo, hi], whose linear interpolation reads chunk i (those between its neighbours)."""
    if hi < lo:
        return []
    out = []
    for i, centre in enumerate(table_wl):
        left = table_wl[i - 1] if i > 0 else centre
        right = table_wl[i + 1] if i + 1 < len(table_wl) else centre
        a, b = max(left, lo), min(right, hi)
        if a > b:
            continue
        count = max(2, int(math.ceil((b - a) / PLAN_WAVELENGTH_STEP_NM)) + 1)
        out += [(i, float(lam)) for lam in np.linspace(a, b, count)]
    return out


def settings_pol(settings) -> list[str]:
    from rcwa.table import pol_names

    return pol_names(settings.pol)


def _side_name(side: np.ndarray) -> str:
    above, below = bool((side > 0).any()), bool((side < 0).any())
    return "both" if above and below else "above" if above else "below" if below else "none"


def source_rays(theta_deg: np.ndarray, phi_deg: np.ndarray, ex: np.ndarray, ey: np.ndarray, normal: np.ndarray,
                 above: bool) -> np.ndarray:
    """World directions toward where the incident light comes from (the light's side of the element).

    The incident wave travels along (sin t cos p, sin t sin p, -cos t) in the grating frame
    (rcwa's convention: light from above travels toward -z); the light lies the other way.
    Refraction at a flat top changes the polar angle, not the azimuth; the test against
    the light's rectangle uses the in-medium direction, a few degrees off at most."""
    t, p = np.radians(theta_deg), np.radians(phi_deg)
    z = np.cos(t) if above else -np.cos(t)
    return -(np.sin(t) * np.cos(p))[:, None] * ex - (np.sin(t) * np.sin(p))[:, None] * ey + z[:, None] * normal[None]


def plan_scene(spec: SceneSpec, *, measure_cost: bool = True) -> Plan:
    """The plan of a scene (see the module's docstring)."""
    from renderer.build import camera_sensitivities
    from renderer.checks import visible_range

    start = time.perf_counter()
    sens = camera_sensitivities(spec.camera.sensitivities)
    wl = np.unique(np.concatenate([w for w, _ in sens]))
    curves = np.stack([np.interp(wl, w, s, left=0, right=0) for w, s in sens])
    camera_range = visible_range(wl, curves)
    step = ray_step(spec)
    origin, rays = camera_rays(spec, step)
    elements = [plan_element(spec, hit, origin, camera_range, measure_cost=measure_cost)
                for hit in element_hits(spec, origin, rays)]
    for e in elements:
        e.visible_pixels *= step * step  # in pixels of the image, not rays
    glass = [GlassPlan(f"glass[{i}]", count * step * step, g.dispersion, g.dispersion and count > 0)
             for i, (g, count) in enumerate(zip(spec.glass, _glass_visible(spec, origin, rays), strict=True))]
    return Plan(spec.name, camera_range, elements, glass, any(e.visible_pixels for e in elements),
                time.perf_counter() - start)


def format_plan(plan: Plan) -> str:
    """The plan as a readable table."""
    lines = [f"plan for {plan.scene}: the camera sees {plan.camera_wavelength_range_nm[0]:g}-"
             f"{plan.camera_wavelength_range_nm[1]:g} nm (a channel at >= 1 % of its peak)"]
    if not plan.elements:
        lines.append("no diffractive element: no RCWA at all")
    for e in plan.elements:
        lines.append(f"\n{e.key}: structure {e.structure}, {e.visible_pixels} pixels in view, camera on the "
                     f"{e.camera_side} side, {'see-through' if e.see_through else 'opaque (R only)'}")
        if not e.visible_pixels:
            lines.append("  not in view: left out")
            continue
        lines += [
            f"  tables        {', '.join(e.tables) or 'none'}",
            f"  orders        {len(e.orders_needed)} of {len(e.orders_kept)} kept orders can reach the camera",
            f"  wavelengths   {e.wavelength_range_nm[0]:g}-{e.wavelength_range_nm[1]:g} nm",
            f"  directions    {e.directions_needed} of {e.directions_total} (wavelength, theta, phi) nodes "
            f"({e.fraction:.0%}); theta "
            f"{_range_text(e.theta_range_deg)}, phi {_range_text(e.phi_range_deg)} deg; symmetry {e.symmetry}",
            f"  light         {e.direct_light_share:.1%} of the needed lookups see the light directly; the rest is "
            f"lit by the box's diffuse walls (kept)",
            f"  cost          whole table ~{e.seconds_whole:.0f} s, {e.megabytes_whole:.1f} MB; planned "
            f"~{e.seconds_planned:.0f} s (measured per direction here)",
            f"  other nodes   {'x'.join(map(str, e.fill_orders))} orders retained (paths that reach the element after a "
            f"diffuse bounce){_fill_error_text(e.fill_error)}",
        ]
        lines += [f"  note          {n}" for n in e.notes]
    for g in plan.glass:
        state = ("dispersive" if g.dispersion_needed else
                 "not in view: its dispersion is not needed" if g.dispersion_in_scene and not g.visible_pixels else
                 "mean index (the scene's choice)")
        lines.append(f"{g.key}: {g.visible_pixels} pixels in view; {state}")
    return "\n".join(lines)


def _fill_error_text(error: dict[str, float]) -> str:
    return f": |dR| median {error['median']:.3f}, max {error['max']:.3f} on a sample" if error else ""


def _range_text(r: tuple[float, float] | None) -> str:
    return "-" if r is None else f"{r[0]:g}-{r[1]:g}"
