"""The scene's meshes as PLY files in the user's cache: the box's quads and the CDs' annuli.

A mesh is named by the hash of its text (workbench.core.cache, ``meshes/``), written
atomically under the entry's lock and checked against its name when reused.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from renderer.placement import box_points_m
from workbench.core.cache import entry_lock, entry_path
from workbench.core.files import atomic_write_text

CD_SEGMENTS = 256


def _ply_text(vertices: np.ndarray, faces: np.ndarray, uv: np.ndarray | None = None) -> str:
    lines = ["ply", "format ascii 1.0", f"element vertex {len(vertices)}",
             "property float x", "property float y", "property float z"]
    if uv is not None:
        lines += ["property float u", "property float v"]
    lines += [f"element face {len(faces)}", "property list uchar int vertex_indices", "end_header"]
    rows = [" ".join(f"{c:.9g}" for c in (list(p) + (list(uv[i]) if uv is not None else []))) for i, p in enumerate(vertices)]
    rows += [f"3 {a} {b} {c}" for a, b, c in faces]
    return "\n".join(lines + rows) + "\n"


def _cached_ply(text: str) -> Path:
    """The cache entry holding ``text``, written when missing or damaged."""
    digest = hashlib.sha256(text.encode()).hexdigest()[:20]
    path = entry_path("meshes", digest + ".ply")
    if not _mesh_intact(path, digest):
        with entry_lock(path):
            if not _mesh_intact(path, digest):  # another process may have written it meanwhile
                atomic_write_text(path, text)
    return path


def _mesh_intact(path: Path, digest: str) -> bool:
    """A cached mesh is reused only when its bytes still hash to its name."""
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()[:20] == digest
    except OSError:
        return False


def quad_mesh(points_mm, scale=(1.0, 1.0, 1.0)) -> Path:
    """A quad of the measured box (corners in mm), scaled to the scene's box, in metres."""
    return _cached_ply(_ply_text(box_points_m(points_mm, scale), np.array([[0, 1, 2], [0, 2, 3]])))


def annulus_mesh(inner: float, outer: float) -> Path:
    """An annulus in the xy-plane (normal +z) with u radial and v the angle (dp/du radial)."""
    angles = np.linspace(0, 2 * np.pi, CD_SEGMENTS + 1)
    ring = lambda r: np.stack([r * np.cos(angles), r * np.sin(angles), np.zeros_like(angles)], 1)  # noqa: E731
    vertices = np.concatenate([ring(inner), ring(outer)])
    n = len(angles)
    uv = np.concatenate([np.stack([np.zeros(n), angles / (2 * np.pi)], 1), np.stack([np.ones(n), angles / (2 * np.pi)], 1)])
    faces = []
    for i in range(CD_SEGMENTS):
        faces += [[i, n + i, n + i + 1], [i, n + i + 1, i + 1]]
    return _cached_ply(_ply_text(vertices, np.array(faces), uv))
