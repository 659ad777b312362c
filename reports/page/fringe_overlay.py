"""The CD's band edges drawn on the image, and the photo-render offsets against azimuth and radius.

The overlay is an inline SVG in the image's own pixel coordinates, laid over the A/B canvas
inside the same zoomed and panned stage (reports.page.html), hidden until its toggle (or the O key) is pressed:

* photo edges (as compared: the frame as taken) as rings, coloured by the offset of their
  render pair along the profile: green within OFFSET_GOOD_PX (issue 15's median bar),
  orange within OFFSET_FAIR_PX (its 95th percentile bar), red beyond; grey where unpaired;
* the render's paired edges (through the photo's sensor) as crosses;
* the grating equation's predicted edges as dots, each with its uncertainty band from the
  calibration (+- fringe_plot.BAND_SIGMAS RMS spreads of the drawn cameras) as a grey bar
  along its profile. The profile's direction is drawn from the CD's expected centre: along
  the radius for radial profiles and across it for circles (in the image, a circle's
  tangent is perpendicular to the line to the ellipse's centre only approximately; the bar
  is a drawing, its length is the band's).

Edge positions follow OpenCV's pixel convention (a pixel's centre at integer
coordinates); the SVG's pixel i spans [i, i + 1], hence the half-pixel shift.
"""

from __future__ import annotations

import numpy as np

from reports.page.fringe_plot import BAND_SIGMAS
from reports.page.html import svg_data_uri

OFFSET_GOOD_PX = 0.5
OFFSET_FAIR_PX = 1.5
SHOWN_QUALITIES = ("ok", "overlap", "clipped")
COLOURS = {"good": "#2ca02c", "fair": "#ff9f1c", "poor": "#d62728", "unpaired": "#9a9a9a"}


def offset_class(offset_px: float | None) -> str:
    if offset_px is None or not np.isfinite(offset_px):
        return "unpaired"
    size = abs(offset_px)
    return "good" if size <= OFFSET_GOOD_PX else "fair" if size <= OFFSET_FAIR_PX else "poor"


def _shown(edge) -> bool:
    return bool(np.isfinite(edge.position) and np.isfinite(edge.x) and np.isfinite(edge.y)
                and edge.quality in SHOWN_QUALITIES)


def _prediction_bars(measured: dict, band: dict, centre: np.ndarray) -> list[str]:
    out = []
    for kind, e in measured["edges"]["prediction"]:
        width = band.get(e.key())
        if width is None or not _shown(e):
            continue
        radial = np.array([e.x, e.y]) - centre
        radial /= max(float(np.linalg.norm(radial)), 1e-9)
        along = radial if kind == "radius" else np.array([-radial[1], radial[0]])
        a, b = np.array([e.x, e.y]) + 0.5 + np.outer([-1, 1], BAND_SIGMAS * width * along)
        out.append(f"<line class='band' x1='{a[0]:.2f}' y1='{a[1]:.2f}' x2='{b[0]:.2f}' y2='{b[1]:.2f}'/>")
    return out


def overlay_svg(measured: dict, band: dict | None, centre_px, width: int, height: int) -> str:
    """The overlay's inline <svg> (module docstring); every number is formatted here, no text from files."""
    pairs = measured["pairs"]["photo_render"]
    offset_of = {id(p.a): p.offset_px for p in pairs}
    photo_key = "photo_as_taken" if "photo_as_taken" in measured["edges"] else "photo"
    parts = _prediction_bars(measured, band or {}, np.asarray(centre_px, float))
    for _kind, e in measured["edges"]["prediction"]:
        if _shown(e):
            parts.append(f"<circle class='prediction' cx='{e.x + 0.5:.2f}' cy='{e.y + 0.5:.2f}' r='0.6'/>")
    for p in pairs:
        x, y = p.b.x + 0.5, p.b.y + 0.5
        parts.append(f"<path class='render' d='M{x - 1:.2f} {y - 1:.2f}L{x + 1:.2f} {y + 1:.2f}"
                     f"M{x - 1:.2f} {y + 1:.2f}L{x + 1:.2f} {y - 1:.2f}'/>")
    for _kind, e in measured["edges"][photo_key]:
        if _shown(e):
            cls = offset_class(offset_of.get(id(e)))
            parts.append(f"<circle class='photo {cls}' cx='{e.x + 0.5:.2f}' cy='{e.y + 0.5:.2f}' r='1.4'/>")
    style = ("<style>.band{stroke:#bbb;stroke-width:0.5}.prediction{fill:#fff}"
             ".render{stroke:#ffdd00;stroke-width:0.35;fill:none}.photo{fill:none;stroke-width:0.45}"
             + "".join(f".{name}{{stroke:{colour}}}" for name, colour in COLOURS.items()) + "</style>")
    return (f"<svg id='fringe-overlay' xmlns='http://www.w3.org/2000/svg' width='{width}' height='{height}' "
            f"viewBox='0 0 {width} {height}' style='position:absolute;left:0;top:0;pointer-events:none;display:none'>"
            f"{style}{''.join(parts)}</svg>")


OVERLAY_LEGEND = (f"rings: photo edges, green within {OFFSET_GOOD_PX:g} px of the render's, orange within "
                  f"{OFFSET_FAIR_PX:g} px, red beyond, grey unpaired; yellow crosses: the render's; white dots: the "
                  f"prediction, grey bars its +- {BAND_SIGMAS:g} sigma band from the calibration")


def offset_plot(measured: dict, cd_radius_px: float) -> str:
    """Photo - render offsets (px) against azimuth (circle profiles) and against radius (radial
    profiles), each with an error bar of the two edges' combined standard deviation; SVG data: URI."""
    import matplotlib  # deferred: start-up time

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9.0, 3.2), dpi=80)
    for ax, kind, label in ((axes[0], "circle", "azimuth on the CD (deg)"), (axes[1], "radius", "radius (px)")):
        pairs = [p for p in measured["pairs"]["photo_render"] if p.a.kind == kind and np.isfinite(p.offset_px)]
        if pairs:
            x = np.array([p.a.coordinate if kind == "circle" else p.a.coordinate * cd_radius_px for p in pairs])
            y = np.array([p.offset_px for p in pairs])
            err = np.array([np.hypot(p.a.sigma_px, p.b.sigma_px) for p in pairs])
            colours = [COLOURS[offset_class(v)] for v in y]
            ax.errorbar(x, y, yerr=err, fmt="none", ecolor="0.6", elinewidth=0.7)
            ax.scatter(x, y, s=10, c=colours)
        ax.axhline(0.0, color="0.3", linewidth=0.6)
        ax.set_xlabel(label)
        ax.set_ylabel("photo - render (px)")
        ax.set_title(f"{'circles' if kind == 'circle' else 'radii'}: {len(pairs)} edge pairs", fontsize=10)
    fig.tight_layout()
    uri = svg_data_uri(fig)
    plt.close(fig)
    return uri
