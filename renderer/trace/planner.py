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
[Lange 2021, Eq. 2], with the sign of workbench.core.conventions; tangential k is
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

The estimated time of a table is measured (renderer.table_cost): a short sweep at the
table's orders, timed, scaled to the table's directions and wavelengths on this machine's cores,
plus its truncation-error sample (rcwa.table.truncation), run once here and scaled to its
wavelengths; the plan shows the sample on a line of its own.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

import rcwa
from rcwa import symmetry
from rcwa.structure import Structure
from rcwa.symmetry import MirrorSymmetry
from rcwa.table import NodePlan, TableSettings, kept_indices, table_symmetry, transmits
from renderer.camera_coverage import visible_range
from renderer.placement import frame_to
from renderer.scene import CD_TOP_THICKNESS_M, CDSpec, GratingSpec, SceneSpec
from renderer.spectra import camera_sensitivities, on_common_grid
from renderer.table_cost import table_cost, truncation_text
from renderer.tables import scene_settings_for
from renderer.trace.geometry import incident_k, light_rectangle, plane_hits

PLAN_WAVELENGTH_STEP_NM = 5.0  # wavelengths sampled for the domain; the tables' own steps are 10 nm or more
NODE_MARGIN = 0  # extra grid nodes around a needed cell: none, since one ray per pixel is far denser than any table grid
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
    truncation: dict[str, Any] = field(default_factory=dict)  # renderer.table_cost.TruncationCost, its seconds included
    notes: list[str] = field(default_factory=list)
    mask: np.ndarray | None = field(default=None, repr=False)

    @property
    def fraction(self) -> float:
        return self.directions_needed / self.directions_total if self.directions_total else 0.0

    def node_plan(self) -> NodePlan | None:
        """The rcwa.table.NodePlan a render builds this element's table with: out of view,
        every node is a fill node (paths can still reach the element after a bounce)."""
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


@dataclass(frozen=True)
class ElementHit:
    """Where the planner's camera rays meet one CD or grating (world frame, metres).

    ``points`` (N, 3): the hit points in view; ``axis`` (N, 3): the grating frame's x axis
    at each (a CD's radial direction, a plate's frame x); ``normal`` (3,): the element's
    normal; ``top``: seen through a CD's flat polycarbonate top.
    """

    key: str  # the scene's element key, ``cd[0]``, ``grating[0]``
    element: CDSpec | GratingSpec
    points: np.ndarray
    axis: np.ndarray
    normal: np.ndarray
    top: bool


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


def element_hits(spec: SceneSpec, origin: np.ndarray, rays: np.ndarray) -> list[ElementHit]:
    """For each CD and grating: the hit points the camera sees, the grating axis there and the normal."""
    out = []
    for i, cd in enumerate(spec.cds):
        frame = frame_to(cd.normal, cd.rotation_deg)
        normal = frame[:, 2]
        center = np.asarray(cd.center, float)
        points, ok = plane_hits(origin, rays, center, normal)
        radius = np.linalg.norm(points - center, axis=1)
        ok &= (radius >= cd.inner_radius) & (radius <= cd.outer_radius)
        radial = (points[ok] - center) / np.maximum(radius[ok, None], 1e-12)
        out.append(ElementHit(f"cd[{i}]", cd, points[ok], radial, normal, cd.top_surface))
    for i, g in enumerate(spec.gratings):
        frame = frame_to(g.normal, g.rotation_deg)
        center = np.asarray(g.center, float)
        points, ok = plane_hits(origin, rays, center, frame[:, 2])
        local = (points - center) @ frame
        ok &= (np.abs(local[:, 0]) <= g.size[0] / 2) & (np.abs(local[:, 1]) <= g.size[1] / 2)
        out.append(ElementHit(f"grating[{i}]", g, points[ok], np.repeat(frame[:, 0][None], int(ok.sum()), axis=0),
                              frame[:, 2], False))
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
    k = incident_k(omega_t, m, n, lam, period, n_cam)
    kx, ky = k[:, 0], k[:, 1]
    s = np.hypot(kx, ky) / n_light
    ok = s < 1.0
    theta = np.degrees(np.arcsin(np.minimum(s, 1.0)))
    phi = np.degrees(np.arctan2(ky, kx))
    return theta, phi, ok


# ---------------------------------------------------------------- the plan


TABLE_NAMES = ("R", "T", "R_below", "T_below")  # the tables a camera ray can read: each side's reflection and transmission


@dataclass(frozen=True)
class _ElementTable:
    """The table an element's scene options ask for, as the planner reads it."""

    structure: Structure
    settings: TableSettings
    sym: MirrorSymmetry
    see_through: bool  # light reaches the camera through the element (not reflection only)
    kept: list[tuple[int, int]]  # the kept orders (m, n), in the sweep's order

    @property
    def grid_theta(self) -> np.ndarray:
        return np.asarray(self.settings.theta_deg)

    @property
    def grid_phi(self) -> np.ndarray:
        return np.asarray(self.settings.phi_deg)

    @property
    def wavelengths(self) -> np.ndarray:
        return np.asarray(self.settings.wavelengths_nm)

    @property
    def nodes(self) -> int:
        """The whole table's (wavelength, theta, phi) nodes."""
        return len(self.grid_theta) * len(self.grid_phi) * len(self.wavelengths)


@dataclass(frozen=True)
class _SideRays:
    """The camera rays that meet an element from one side, in its grating frame."""

    name: str  # "above" (the superstrate's side) or "below"
    omega_t: np.ndarray  # (N, 2) tangential components of the direction toward the camera (along axis, ey)
    points: np.ndarray  # (N, 3) hit points
    axis: np.ndarray  # (N, 3) the grating frame's x axis
    ey: np.ndarray  # (N, 3) the grating frame's y axis (normal x axis)


@dataclass
class _Lookups:
    """What the camera's rays read of an element's tables: the nodes per table (wavelength,
    theta, phi), the orders that reach the camera, and how many lookups see the light directly."""

    masks: dict[str, np.ndarray]
    orders: set[tuple[int, int]] = field(default_factory=set)
    direct: int = 0
    total: int = 0


def _table_settings(element: CDSpec | GratingSpec, structure: Structure, where: str,
                    scene_file: str | None) -> TableSettings:
    options = {k: v for k, v in dict(element.table).items() if k != "path"}
    preset = options.pop("preset", "draft")
    return scene_settings_for(structure, preset, options, where, scene_file)


def _element_table(spec: SceneSpec, hit: ElementHit) -> _ElementTable:
    structure = rcwa.load_structure(hit.element.structure)
    settings = _table_settings(hit.element, structure, hit.key, spec.source)
    sym = table_symmetry(structure, settings.orders, settings.keep, settings.use_symmetry)
    see_through = transmits(structure, settings) and not settings.reflection_only
    ms, ns = kept_indices(settings.keep)
    return _ElementTable(structure, settings, sym, see_through, [(int(m), int(n)) for m, n in zip(ms, ns, strict=True)])


def _indices(structure: Structure, wavelengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n1 = np.sqrt(np.asarray(structure.superstrate.epsilon(wavelengths), dtype=complex)).real
    n3 = np.sqrt(np.asarray(structure.substrate.epsilon(wavelengths), dtype=complex)).real
    return n1, n3


def plan_element(spec: SceneSpec, hit: ElementHit, origin: np.ndarray, camera_range: tuple[float, float],
                 *, measure_cost: bool = True) -> ElementPlan:
    """What one element needs: the table nodes its camera rays read (module docstring), and the cost."""
    table = _element_table(spec, hit)
    wavelengths = table.settings.wavelengths_nm
    lo, hi = max(camera_range[0], min(wavelengths)), min(camera_range[1], max(wavelengths))
    samples = _chunk_samples(table.wavelengths, lo, hi)
    sides = _camera_sides(hit, origin)
    found = _lookups(spec, hit, table, sides, samples)
    used, union = _union(found.masks)
    seen = np.any(union, axis=0)  # (theta, phi) nodes some wavelength needs
    grid_theta, grid_phi = table.grid_theta, table.grid_phi
    cost = table_cost(table.structure, table.settings, table.see_through, len(table.kept), found.masks,
                      bool(measure_cost and samples))
    sym = table.sym
    return ElementPlan(
        key=hit.key, structure=table.structure.name, visible_pixels=int(len(hit.points)),
        camera_side=_side_name([rays.name for rays in sides]), see_through=bool(table.see_through), tables=used,
        orders_needed=sorted(found.orders), orders_kept=table.kept, wavelength_range_nm=(float(lo), float(hi)),
        symmetry=f"{sym.describe()}, azimuths stored {sym.azimuth_range()[0]:g}-{sym.azimuth_range()[1]:g} deg",
        grid_theta_deg=[float(x) for x in grid_theta], grid_phi_deg=[float(x) for x in grid_phi],
        directions_needed=int(union.sum()), directions_total=table.nodes,
        theta_range_deg=_seen_range(grid_theta, seen.any(axis=1)), phi_range_deg=_seen_range(grid_phi, seen.any(axis=0)),
        direct_light_share=found.direct / found.total if found.total else 0.0,
        seconds_whole=cost.seconds_whole, seconds_planned=cost.seconds_planned, megabytes_whole=cost.megabytes_whole,
        fill_orders=cost.fill_orders, fill_error=cost.fill_error, truncation=asdict(cost.truncation),
        notes=_notes(samples, hit), mask=union,
    )


def _camera_sides(hit: ElementHit, origin: np.ndarray) -> list[_SideRays]:
    """The camera's rays on each side of the element that they meet it from."""
    omega = origin - hit.points
    omega /= np.maximum(np.linalg.norm(omega, axis=1, keepdims=True), 1e-300)
    side = omega @ hit.normal
    ey = np.cross(hit.normal, hit.axis)
    omega_t = np.stack([np.einsum("ij,ij->i", omega, hit.axis), np.einsum("ij,ij->i", omega, ey)], axis=1)
    out = []
    for name, on_side in {"above": side > 0, "below": side < 0}.items():
        if on_side.any():
            out.append(_SideRays(name, omega_t[on_side], hit.points[on_side], hit.axis[on_side], ey[on_side]))
    return out


def _channels(sides: list[_SideRays], see_through: bool) -> list[tuple[_SideRays, str, bool]]:
    """(rays, table, transmitted) for each table the rays of each side read: reflection on
    their side, and transmission from the other side for a see-through element."""
    channels = []
    for rays in sides:
        if rays.name == "below" and not see_through:
            continue
        channels.append((rays, "R" if rays.name == "above" else "R_below", False))
        if see_through:
            channels.append((rays, "T_below" if rays.name == "above" else "T", True))
    return channels


def _lookups(spec: SceneSpec, hit: ElementHit, table: _ElementTable, sides: list[_SideRays],
             samples: list[tuple[int, float]]) -> _Lookups:
    """The nodes the camera's rays read: over sides, tables, sampled wavelengths and kept orders."""
    shape = (len(table.wavelengths), len(table.grid_theta), len(table.grid_phi))
    found = _Lookups({name: np.zeros(shape, bool) for name in TABLE_NAMES})
    for rays, table_name, transmitted in _channels(sides, table.see_through):
        for chunk, lam in samples:
            n_cam, n_light = _refractive_indices(table.structure, lam, rays.name, transmitted, hit.top)
            for order in table.kept:
                _mark_order(found, found.masks[table_name][chunk], spec, hit, table, rays, order, lam, n_cam, n_light,
                            above=(rays.name == "above") != transmitted)
    return found


def _refractive_indices(structure: Structure, lam: float, side: str, transmitted: bool, top: bool) -> tuple[float, float]:
    """The indices of the camera's medium (n_cam) and of the incident light's (n_light) at ``lam``."""
    n1, n3 = _indices(structure, np.array([lam]))
    # omega_t is the camera's direction in air; behind a flat top the BWDF's n_pc sin(theta_pc) is sin(theta_air)
    n_cam = 1.0 if top else (n1[0] if side == "above" else n3[0])
    n_side = n1[0] if side == "above" else n3[0]  # the table's angles are in this medium
    n_light = (n3[0] if side == "above" else n1[0]) if transmitted else n_side
    return n_cam, n_light


def _mark_order(found: _Lookups, chunk_mask: np.ndarray, spec: SceneSpec, hit: ElementHit, table: _ElementTable,
                rays: _SideRays, order: tuple[int, int], lam: float, n_cam: float, n_light: float, *,
                above: bool) -> None:
    """Mark in ``chunk_mask`` the nodes order (m, n) at ``lam`` reads for the rays, and count
    the lookups whose incident light comes straight from the ceiling light (``above``: the
    light's side of the element)."""
    m, n = order
    theta, phi, ok = incident_directions(rays.omega_t, m, n, lam, table.structure.period, n_cam, n_light)
    if not ok.any():
        return
    found.orders.add(order)
    sym = table.sym
    folded = fold_azimuths(phi[ok], sym.x, sym.y, sym.diagonal)
    _mark(chunk_mask, table.grid_theta, table.grid_phi, theta[ok], folded)
    src = source_rays(theta[ok], phi[ok], rays.axis[ok], rays.ey[ok], hit.normal, above=above)
    found.direct += int(np.count_nonzero(light_rectangle(spec).hit_by(rays.points[ok], src)))
    found.total += int(ok.sum())


def _union(masks: dict[str, np.ndarray]) -> tuple[list[str], np.ndarray]:
    """The tables some ray reads, and the nodes any of them needs (wavelength, theta, phi)."""
    used = [name for name, mk in masks.items() if mk.any()]
    union = np.zeros_like(masks["R"])
    for name in used:
        union |= masks[name]
    return used, union


def _seen_range(grid: np.ndarray, seen: np.ndarray) -> tuple[float, float] | None:
    """The range of the grid's values some needed node has, or None when none is needed."""
    return (float(grid[seen].min()), float(grid[seen].max())) if seen.any() else None


def _notes(samples: list[tuple[int, float]], hit: ElementHit) -> list[str]:
    notes = []
    if not samples:
        notes.append("the table's wavelengths miss the camera's range: nothing to look up")
    if not len(hit.points):
        notes.append("the camera does not see this element: nothing to simulate")
    if hit.top:
        notes.append(f"seen through a {CD_TOP_THICKNESS_M * 1e3:g} mm flat polycarbonate top: tangential k is kept across it")
    return notes


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


def _side_name(sides: list[str]) -> str:
    above, below = "above" in sides, "below" in sides
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
    start = time.perf_counter()
    wl, curves = on_common_grid(camera_sensitivities(spec.camera.sensitivities))
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


def planned_nodes(spec: SceneSpec, margin: int = 0) -> dict[str, NodePlan | None]:
    """The planner's rcwa.table.NodePlan per element key (``cd[0]``).

    ``margin``: grow each mask by this many grid nodes in theta and phi, so that the
    table also serves cameras near this one (a run plans with the scene's camera and
    renders with the fitted one; renderer.tables then finds the table)."""
    from scipy.ndimage import binary_dilation  # deferred: start-up time

    plan = plan_scene(spec, measure_cost=False)
    nodes = {e.key: e.node_plan() for e in plan.elements}
    if margin:
        grow = np.ones((1, 2 * margin + 1, 2 * margin + 1), bool)
        nodes = {k: None if n is None else NodePlan(binary_dilation(n.mask, grow), n.fill_orders)
                 for k, n in nodes.items()}
    return nodes


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
            truncation_text(e.truncation, e.seconds_whole),
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
