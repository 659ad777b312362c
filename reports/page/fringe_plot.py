"""The report's fringe plot: band edges' radius against azimuth, with the prediction's uncertainty band."""

from __future__ import annotations

import numpy as np

from reports.page.html import svg_data_uri

BAND_SIGMAS = 2.0  # the plotted band: the predicted edge +- this many RMS spreads (about 95 %)


def _band_bars(measured: dict, band: dict[tuple, float], cd_radius_px: float) -> list[tuple[float, float, float, float]]:
    """(azimuth deg, radius px, azimuth half-width deg, radius half-width px) of the prediction's
    uncertainty band at each predicted edge: along the profile, +- BAND_SIGMAS RMS spreads."""
    bars = []
    for kind, e in measured["edges"]["prediction"]:
        width = band.get(e.key())
        if width is None or not np.isfinite(e.position):
            continue
        half = BAND_SIGMAS * width
        if kind == "circle":  # along the circle: px to degrees of azimuth at this radius
            bars.append((e.coordinate, e.label * cd_radius_px, float(np.degrees(half / max(e.label * cd_radius_px, 1e-6))), 0.0))
        else:
            bars.append((e.label, e.coordinate * cd_radius_px, 0.0, half))
    return bars


def fringe_plot(measured: dict, cd_radius_px: float, band: dict[tuple, float] | None = None) -> str:
    """The page's fringe plot as an SVG data: URI: every band edge of quality ok, overlap or clipped
    in prediction, photo and render (``measured``: reports.report.measure_fringes), radius (px)
    against azimuth, and the prediction's uncertainty band (``band``: RMS spread per edge key)."""
    import matplotlib  # deferred: start-up time

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 3.6), dpi=80)
    styles = {"prediction": ("k", "."), "photo": ("tab:blue", "o"), "render": ("tab:orange", "x")}
    for name, (colour, marker) in styles.items():
        points = [(e.coordinate if kind == "circle" else e.label, (e.label if kind == "circle" else e.coordinate) * cd_radius_px)
                  for kind, e in measured["edges"][name] if np.isfinite(e.position) and e.quality in ("ok", "overlap", "clipped")]
        if points:
            azimuth, radius = np.array(points).T
            ax.scatter(azimuth, radius, s=9 if marker != "." else 4, c=colour, marker=marker, label=name,
                       linewidths=0.8, alpha=0.8)
    bars = _band_bars(measured, band or {}, cd_radius_px)
    if bars:
        x, y, dx, dy = np.array(bars).T
        ax.errorbar(x, y, xerr=dx, yerr=dy, fmt="none", ecolor="0.5", elinewidth=0.8, capsize=0,
                    label=f"prediction +- {BAND_SIGMAS:g} sigma (calibration)")
    ax.set_xlabel("azimuth on the CD (deg)")
    ax.set_ylabel("radius (px, rim = %.0f)" % cd_radius_px)
    ax.set_title("band edges: radius against azimuth")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    uri = svg_data_uri(fig)
    plt.close(fig)
    return uri
