"""The lens's uncertainty maps on the report page: the calibration's projection uncertainty map
and its cross-validation diff (calibration.intrinsics.projection_uncertainty; mrcal's "Projection
uncertainty" and "Cross-validation" [mrcal]; issue 26 item 2), beside the summary's lens row.

Where they are: intrinsics.json beside calibration.json (``calibrate DATASET`` and verify write
both into one folder; a report may also be given intrinsics.json itself). Each map is read from
its 16-bit PNG where intrinsics.json names one that exists (``calibrate intrinsics`` writes them
beside it: value / PNG_SCALE px, 65535 where no ray or over range), else from the grid values
the record keeps (``map_px``: the uncertainty's ``std``, the first split's ``diff``). Both are
grid-node values (every SAMPLE_STEP_PX pixels, corners and centre on the grid), drawn bilinearly
between the nodes over the image's own pixel frame, colour-mapped with a colour bar in pixels,
and the CD's region outlined where its mask is given and has the maps' image size. A calibration
without them gets one line saying so.
"""

from __future__ import annotations

import base64
import html
import io
import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from calibration.intrinsics.projection_uncertainty import PNG_SCALE, grid_axes
from reports.page import html as page

PNG_NO_VALUE = 65535
PANELS = (("projection_uncertainty", "std", "projection uncertainty (1 std, worst direction)"),
          ("cross_validation", "diff", "cross-validation diff (two halves of the board views)"))
FIGURE_DPI = 80
PANEL_INCHES = (4.6, 3.6)   # per map (width, height); the figure is the maps side by side


@dataclass
class LensMap:
    """One grid map (px) at nodes ``us`` x ``vs`` of a ``width`` x ``height`` image, and where it came from."""

    title: str
    us: np.ndarray
    vs: np.ndarray
    values_px: np.ndarray        # (len(vs), len(us)); NaN where no ray
    source: str
    caption: str


def intrinsics_record(calibration: Path) -> tuple[dict, Path] | str:
    """intrinsics.json's record and path for a report's ``--calibration`` file, or why there is none."""
    try:
        own = json.loads(Path(calibration).read_text())
    except (OSError, ValueError):
        return f"no lens maps: {Path(calibration).name} could not be read as JSON"
    if isinstance(own, dict) and "projection_uncertainty" in own:
        return own, Path(calibration)
    beside = Path(calibration).with_name("intrinsics.json")
    if not beside.is_file():
        return (f"no lens maps: the calibration ({Path(calibration).name}) has no intrinsics.json beside it "
                "(no board views were calibrated)")
    try:
        record = json.loads(beside.read_text())
    except ValueError:
        return f"no lens maps: {beside} is not valid JSON"
    if not isinstance(record, dict) or "projection_uncertainty" not in record:
        return f"no lens maps: {beside} holds no projection uncertainty (calibrated before it was computed)"
    return record, beside


def _grid_values(block: dict, key: str) -> np.ndarray | None:
    grid = block.get("map_px") or {}
    if key not in grid:
        return None
    values = np.asarray(grid[key], float)
    values[values < 0] = np.nan
    return values


def _png_values(path: Path) -> np.ndarray | None:
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED) if path.is_file() else None
    if image is None or image.dtype != np.uint16 or image.ndim != 2:
        return None
    return np.where(image == PNG_NO_VALUE, np.nan, image / PNG_SCALE)


def _axes(block: dict, width: int, height: int, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    grid = block.get("map_px") or {}
    if "u" in grid and "v" in grid:
        return np.asarray(grid["u"], float), np.asarray(grid["v"], float)
    step = float(block.get("grid_step_px") or (width - 1) / max(shape[1] - 1, 1))
    return grid_axes((width, height), step)


def _caption(key: str, block: dict) -> str:
    if key == "projection_uncertainty":
        s = block.get("std_px") or {}
        return (f"median {page.format_number(s.get('median'), 3)} px, centre {page.format_number(s.get('centre'), 3)} px"
                f", largest {page.format_number(s.get('max'), 3)} px")
    diff, predicted = block.get("diff_px") or {}, block.get("predicted_px") or {}
    ratio = (block.get("splits") or {}).get("pooled_ratio")
    return (f"median {page.format_number(diff.get('median'), 3)} px against {page.format_number(predicted.get('median'), 3)}"
            f" px predicted (pooled ratio over the splits {page.format_number(ratio, 3)})"
            + ("; the model is too poor for the data" if block.get("too_poor") else ""))


def read_maps(calibration: Path) -> list[LensMap] | str:
    """The maps of the calibration behind a report's ``--calibration`` file (module docstring), or
    one line saying why there are none (a malformed record among them: the figure never stops a report)."""
    found = intrinsics_record(calibration)
    if isinstance(found, str):
        return found
    try:
        return _maps_of(*found)
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        return f"no lens maps: {found[1].name} is malformed ({type(error).__name__}: {error})"


def _maps_of(record: dict, where: Path) -> list[LensMap] | str:
    width, height = int(record["width"]), int(record["height"])
    maps = []
    for key, grid_key, title in PANELS:
        block = record.get(key) or {}
        image = block.get("image")
        values = _png_values(where.with_name(image)) if image else None
        source = f"{image} beside {where.name}" if values is not None else f"{where.name}'s grid values"
        values = values if values is not None else _grid_values(block, grid_key)
        if values is None:
            continue
        us, vs = _axes(block, width, height, values.shape)
        if values.shape != (len(vs), len(us)):
            continue
        maps.append(LensMap(title, us, vs, values, source, _caption(key, block)))
    if not maps:
        return f"no lens maps: {where.name} holds no map values (neither its PNGs nor their grid)"
    return maps


def _dense(m: LensMap, width: int, height: int) -> np.ndarray:
    """The grid map drawn over every pixel (bilinear between the nodes; NaN nodes stay NaN nearby)."""
    from scipy.interpolate import RegularGridInterpolator  # deferred: start-up time

    sample = RegularGridInterpolator((m.vs, m.us), m.values_px, bounds_error=False, fill_value=np.nan)
    v, u = np.mgrid[0:height, 0:width]
    return sample(np.stack([v.ravel(), u.ravel()], 1).astype(float)).reshape(height, width)


def figure_png(maps: list[LensMap], cd_mask: np.ndarray | None) -> str:
    """The maps side by side, each with its colour bar in px and the CD outlined, as a PNG data: URI."""
    import matplotlib  # deferred: start-up time

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width, height = int(round(maps[0].us[-1])) + 1, int(round(maps[0].vs[-1])) + 1
    fig, axes = plt.subplots(1, len(maps), figsize=(PANEL_INCHES[0] * len(maps), PANEL_INCHES[1]), dpi=FIGURE_DPI,
                             squeeze=False)
    for ax, m in zip(axes[0], maps, strict=True):
        dense = _dense(m, width, height)
        finite = dense[np.isfinite(dense)]
        vmax = float(np.percentile(finite, 99)) if finite.size else 1.0
        shown = ax.imshow(dense, cmap=page.COLORMAP, vmin=0.0, vmax=max(vmax, 1e-6), interpolation="nearest")
        bar = fig.colorbar(shown, ax=ax, fraction=0.046, pad=0.03)
        bar.set_label("px")
        if cd_mask is not None and cd_mask.shape == (height, width) and cd_mask.any():
            ax.contour(cd_mask.astype(float), levels=[0.5], colors="white", linewidths=1.0)
        ax.set_title(m.title, fontsize=9)
        ax.set_xlabel("x (px)", fontsize=8)
        ax.set_ylabel("y (px)", fontsize=8)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def _model_note(calibration: Path) -> str:
    """The maps' lens model and the distortion terms it fitted (intrinsics.json ``model_choice``)."""
    found = intrinsics_record(calibration)
    record = found[0] if not isinstance(found, str) else {}
    terms = ((record.get("model_choice") or {}).get("terms") or {}).get("chosen")
    return f"the {record.get('model', 'pinhole')} model" + (f" fitting {', '.join(terms)}" if terms else "")


def figure_html(calibration: Path, cd_mask: np.ndarray | None = None) -> str:
    """The page's lens-maps figure (or the one line saying why there is none), for the summary block."""
    maps = read_maps(calibration)
    if isinstance(maps, str):
        return f"<p id='lens-maps' class='note'>{html.escape(maps)}</p>"
    outlined = cd_mask is not None and cd_mask.any()
    captions = "; ".join([*(f"{m.title}: {m.caption} (from {m.source})" for m in maps), _model_note(calibration)])
    return (f"<figure id='lens-maps'><img alt='the lens calibration&#39;s projection uncertainty and cross-validation "
            f"diff maps' src='{figure_png(maps, cd_mask)}'><figcaption>{html.escape(captions)}"
            f"{'; the CD outlined in white' if outlined else ''}; colours up to each map's 99th percentile."
            "</figcaption></figure>")
