"""Efficiencies for a fitted layer thickness (the CD's groove depth): RCWA tables at a few
thicknesses, read as one efficiency linear in the thickness between neighbouring ones.

The forward model (reports.scene_fit_model) weights every lit (pixel, wavelength) by the
order's efficiency (reports.prediction_efficiency); a groove depth changes those
efficiencies, not the directions. Re-solving at every evaluation would cost a table per
step, so ``THICKNESS_NODES`` tables are built once across the parameter's bounds, each with
the scene's own table settings (renderer.tables; the user's cache keeps them by content,
so a second fit reuses them), and the efficiency at a thickness is the linear blend of the
two nodes around it. The nodes are close enough for that: across the default bounds (+-30 %
of 0.11 um, rcwa.structures' cd) neighbouring nodes differ in phase depth 4 pi n d / lambda
by about 0.4 rad at 500 nm. What it costs is recorded (``seconds``: 7 draft tables in about
10-15 s on 2 cores; the paper preset's about 2 minutes each).
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np
import tomli_w

from rcwa.structure import load_structure
from renderer.fit_parameters import FitParameter
from reports.prediction_efficiency import Efficiency, scene_efficiency

THICKNESS_NODES = 7


class BlendedEfficiency:
    """(1 - w) a + w b of two efficiencies (the same call as reports.prediction_efficiency.Efficiency)."""

    def __init__(self, a: Efficiency, b: Efficiency, w: float):
        self.a, self.b, self.w = a, b, w
        self.source = f"{a.source} .. {b.source} (w = {w:.3f})"

    def __call__(self, m: int, wavelengths_nm: np.ndarray, sin_air: np.ndarray, phi_deg: np.ndarray) -> np.ndarray:
        return ((1.0 - self.w) * self.a(m, wavelengths_nm, sin_air, phi_deg)
                + self.w * self.b(m, wavelengths_nm, sin_air, phi_deg))


def _structure_with_thickness(reference: str, layer: int, thickness: float, folder: Path) -> Path:
    data = tomllib.loads(load_structure(reference).text)
    data["layers"][layer]["thickness"] = float(thickness)
    data["name"] = f"{data.get('name', 'structure')}_d{thickness:.5f}"
    path = folder / f"{data['name']}.toml"
    path.write_text(tomli_w.dumps(data))
    return path


class ThicknessEfficiencies:
    """The CD's efficiencies at ``THICKNESS_NODES`` thicknesses of one layer across ``parameter``'s bounds."""

    def __init__(self, spec, parameter: FitParameter, nodes: int = THICKNESS_NODES):
        started = time.perf_counter()
        index, layer = parameter.cd_index or 0, parameter.layer or 0
        self.values = np.linspace(parameter.lower[0], parameter.upper[0], nodes)
        cd = spec.cds[index]
        self.efficiencies = []
        with tempfile.TemporaryDirectory() as tmp:  # the copies only name the tables, which the cache keeps
            for t in self.values:
                path = _structure_with_thickness(cd.structure, layer, t, Path(tmp))
                cds = list(spec.cds)
                cds[index] = dataclasses.replace(cd, structure=str(path))
                self.efficiencies.append(scene_efficiency(dataclasses.replace(spec, cds=tuple(cds)), index))
        self.seconds = time.perf_counter() - started

    def at(self, thickness: float) -> BlendedEfficiency:
        i = int(np.clip(np.searchsorted(self.values, thickness) - 1, 0, len(self.values) - 2))
        w = float(np.clip((thickness - self.values[i]) / (self.values[i + 1] - self.values[i]), 0.0, 1.0))
        return BlendedEfficiency(self.efficiencies[i], self.efficiencies[i + 1], w)
