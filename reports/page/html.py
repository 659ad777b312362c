"""The report as one self-contained HTML file: works offline, makes no network request.

Everything is embedded: the photo and the render as linear sRGB (after the report's one
display transform) as a pyramid of compressed tiles (reports.page.tiles: the overview
exact in float16, the finer levels of a large photo log-coded JPEG), decoded as the view
needs them and tone-mapped in the browser (exposure 2^EV, then the sRGB curve) into a
canvas the size of the panel; error maps, legends and the fringe plot as data: URIs;
numbers as JSON in a ``<script type="application/json">`` (with ``<`` escaped, so no text
from a file can close it). Every text that comes from a file or the command line (scene
names, file names, metadata, messages) goes through html.escape.

Controls: A/B flip between photo and render (the button, or the F key or space), the
CD's band edges drawn over the image (the fringe-overlay toggle, or the O key),
synchronised zoom (mouse wheel, the + and - buttons, fit, 1:1) and pan (drag) across the image
and error-map panels, an exposure slider acting on the linear data, a choice of error map.
"""

from __future__ import annotations

import base64
import html
import io
import json
from typing import Any

import numpy as np
from PIL import Image

COLORMAP = "magma"
MAX_VIEW = (960, 720)  # the image panels' largest size (CSS pixels); a larger image starts fitted into it


def png_data_uri(rgb8: np.ndarray) -> str:
    """An (H, W, 3) or (H, W, 4) uint8 image as a PNG data: URI."""
    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgb8)).save(buffer, format="PNG", optimize=True)
    return "data:image/png;base64," + base64.b64encode(buffer.getvalue()).decode("ascii")


def false_colour(values: np.ndarray, vmax: float, mask: np.ndarray | None = None) -> np.ndarray:
    """``values`` in [0, vmax] through the colour map, uint8 RGB; nan and unmasked pixels black."""
    from matplotlib import colormaps  # deferred: start-up time

    scaled = np.clip(np.nan_to_num(values, nan=0.0) / max(vmax, 1e-12), 0.0, 1.0)
    rgb = (colormaps[COLORMAP](scaled)[..., :3] * 255).astype(np.uint8)
    if mask is not None:
        rgb[~mask] = 0
    return rgb


def legend_data_uri(width: int = 256, height: int = 14) -> str:
    """The colour map as a horizontal bar (its limits are printed beside it)."""
    ramp = np.tile(np.linspace(0.0, 1.0, width)[None], (height, 1))
    return png_data_uri(false_colour(ramp, 1.0))


def svg_data_uri(figure) -> str:
    buffer = io.StringIO()
    figure.savefig(buffer, format="svg")
    return "data:image/svg+xml;base64," + base64.b64encode(buffer.getvalue().encode("utf-8")).decode("ascii")


def _json_for_script(data: Any) -> str:
    """JSON safe inside a <script> element: '<', '>' and '&' escaped as unicode."""
    text = json.dumps(data, allow_nan=False, default=_finite)
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _finite(value: Any) -> Any:
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def format_number(value: float | None, digits: int = 4) -> str:
    """``digits`` significant figures, never a float's 17; '-' for NaN and None."""
    if value is None or not np.isfinite(value):
        return "-"
    return f"{value:.{digits}g}"


def format_value(value: Any) -> str:
    """A value as a person reads it (escaped HTML): numbers to 4 significant figures, a list of
    numbers as "a, b, c", a dict as a small table of its own, None as '-'; never a repr."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        return format_number(float(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, dict):
        return key_values(value) if value else "-"
    if isinstance(value, (list, tuple, np.ndarray)):
        items = list(value)
        if all(isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool) for v in items):
            return ", ".join(format_value(v) for v in items) if items else "-"
        return "; ".join(format_value(v) for v in items) if items else "-"
    return html.escape(str(value))


def _tip(text: str | None) -> str:
    """A title attribute (the browser's tooltip): what a number means and how it was measured."""
    return f" title='{html.escape(text)}'" if text else ""


def table(rows: list[dict], columns: list[str] | None = None, caption: str | None = None,
          tips: dict[str, str] | None = None) -> str:
    """An HTML table of dicts (every value escaped); ``tips``: a tooltip per column heading."""
    if not rows:
        return "<p class='none'>(none)</p>"
    columns = columns or list(rows[0])
    tips = tips or {}
    head = "".join(f"<th{_tip(tips.get(c))}>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{format_value(r.get(c, ''))}</td>" for c in columns) + "</tr>" for r in rows)
    cap = f"<caption>{html.escape(caption)}</caption>" if caption else ""
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def key_values(pairs: dict[str, Any], tips: dict[str, str] | None = None) -> str:
    """A two-column table of names and values; ``tips``: a tooltip per name."""
    tips = tips or {}
    body = "".join(f"<tr><th{_tip(tips.get(str(k)))}>{html.escape(str(k))}</th><td>{format_value(v)}</td></tr>"
                   for k, v in pairs.items())
    return f"<table class='kv'>{body}</table>"


STYLE = """
body { font: 14px/1.4 system-ui, sans-serif; margin: 16px; background: #f4f4f2; color: #222; }
h1 { font-size: 20px; margin: 0 0 4px; } h2 { font-size: 16px; margin: 20px 0 6px; }
.bar { display: flex; gap: 12px; align-items: center; flex-wrap: wrap; margin: 8px 0; }
.panels { display: flex; gap: 10px; flex-wrap: wrap; }
.panel { background: #111; }
.panel .title { color: #eee; font-size: 12px; padding: 2px 6px; }
.viewport { position: relative; overflow: hidden; cursor: grab; background: #000; }
.stage { position: absolute; left: 0; top: 0; transform-origin: 0 0; pointer-events: none; }
.viewport canvas { position: absolute; left: 0; top: 0; }
.stage canvas, .stage img { display: block; image-rendering: pixelated; }
table { border-collapse: collapse; margin: 4px 0; background: #fff; font-size: 12px; }
th, td { border: 1px solid #ccc; padding: 2px 6px; text-align: right; } th { background: #eee; }
table.kv th { text-align: left; }
.note { background: #fff7d6; border: 1px solid #e0c870; padding: 6px 10px; margin: 6px 0; }
.error { background: #fde2e2; border: 1px solid #d88; padding: 6px 10px; margin: 6px 0; }
.verdict { padding: 8px 12px; margin: 6px 0; border: 1px solid #999; font-size: 15px; }
.verdict-consistent { background: #e3f4e1; } .verdict-model { background: #fde9cf; }
.verdict-camera { background: #e3ecfa; } .verdict-unexplained { background: #fde2e2; }
.legend img { vertical-align: middle; height: 14px; width: 256px; }
.scroll { max-height: 320px; overflow: auto; display: inline-block; }
"""

SCRIPT = r"""
(function () {
  const data = JSON.parse(document.getElementById('report-data').textContent);
  const pyr = data.pyramid, T = pyr.tile, LAST = pyr.levels.length - 1, CACHED_TILES = 96;
  const state = { showing: data.order[0], ev: data.exposure_ev, zoom: data.fit, x: 0, y: 0 };
  // for tests and benchmarks: settled() once every tile the view needs is decoded and drawn
  const viewer = { state, pending: 0, complete: false, queued: false, draws: 0,
                   settled: () => viewer.pending === 0 && !viewer.queued && viewer.complete };
  window.reportState = state; window.reportViewer = viewer;
  const halfTable = new Float32Array(65536), codeTable = new Float32Array(256), code = pyr.log_code;
  for (let h = 0; h < 65536; h++) {
    const s = (h & 0x8000) ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
    halfTable[h] = e === 0 ? s * f * 5.960464477539063e-8 : e === 31 ? (f ? NaN : s * Infinity)
                             : s * Math.pow(2, e - 15) * (1 + f / 1024);
  }
  for (let c = 1; c < 256; c++) codeTable[c] = Math.pow(2, code.lo + (c - 1) * (code.hi - code.lo) / 254);
  function bytesOf(b64) {
    const text = atob(b64), out = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
    return out;
  }
  async function decodeExact(bytes) {  // float16's low bytes then its high bytes, zlib-deflated (reports.page.tiles)
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('deflate'));
    const b = new Uint8Array(await new Response(stream).arrayBuffer()), n = b.length / 2, out = new Float32Array(n);
    for (let i = 0; i < n; i++) out[i] = halfTable[b[i] | (b[n + i] << 8)];
    return out;
  }
  async function decodeLossy(bytes, w, h) {  // 8-bit log code as JPEG (reports.page.tiles)
    const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/jpeg' }),
                                           { colorSpaceConversion: 'none', premultiplyAlpha: 'none' });
    const g = new OffscreenCanvas(w, h).getContext('2d', { willReadFrequently: true });
    g.drawImage(bitmap, 0, 0);
    const px = g.getImageData(0, 0, w, h).data, out = new Float32Array(w * h * 3);
    for (let i = 0, j = 0; i < w * h; i++, j += 3) {
      out[j] = codeTable[px[4 * i]]; out[j + 1] = codeTable[px[4 * i + 1]]; out[j + 2] = codeTable[px[4 * i + 2]];
    }
    return out;
  }
  function tileRect(k, i) {  // [column, row, width, height] in level k's pixels
    const L = pyr.levels[k], c = i % L.columns, r = Math.floor(i / L.columns);
    return [c, r, Math.min(T, L.width - c * T), Math.min(T, L.height - r * T)];
  }
  const linear = new Map(), toned = new Map();  // 'name/k/i' -> Float32Array (null while loading); -> canvas
  function load(name, k, i) {
    const key = name + '/' + k + '/' + i;
    if (linear.has(key)) { const v = linear.get(key); linear.delete(key); linear.set(key, v); return; }
    linear.set(key, null); viewer.pending++;
    const [, , w, h] = tileRect(k, i), bytes = bytesOf(pyr.tiles[name][k][i]);
    (pyr.levels[k].codec === 'float16-shuffled-deflate' ? decodeExact(bytes) : decodeLossy(bytes, w, h)).then(values => {
      linear.set(key, values); viewer.pending--; schedule();
    }, err => { viewer.pending--; console.error('tile ' + key + ' did not decode: ' + err); });
  }
  function evict(keep) {  // the least recently used fine tiles beyond CACHED_TILES (the overview stays)
    for (const key of Array.from(linear.keys())) {
      if (linear.size <= CACHED_TILES) break;
      const parts = key.split('/');
      if (keep.has(key) || Number(parts[parts.length - 2]) === LAST || !linear.get(key)) continue;
      linear.delete(key); toned.delete(key);
    }
  }
  function srgb(v) { v = v <= 0 ? 0 : v >= 1 ? 1 : v; return v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055; }
  function tonedTile(name, k, i) {  // the tile through exposure 2^EV and the sRGB curve, cached per EV
    const key = name + '/' + k + '/' + i, values = linear.get(key), done = toned.get(key);
    if (!values) return null;
    if (done && done.ev === state.ev) return done.canvas;
    const [, , w, h] = tileRect(k, i), canvas = done ? done.canvas : document.createElement('canvas');
    canvas.width = w; canvas.height = h;
    const g = canvas.getContext('2d'), frame = g.createImageData(w, h), px = frame.data, gain = Math.pow(2, state.ev);
    for (let p = 0, j = 0; p < w * h; p++, j += 3) {
      px[4 * p] = 255 * srgb(values[j] * gain) + 0.5; px[4 * p + 1] = 255 * srgb(values[j + 1] * gain) + 0.5;
      px[4 * p + 2] = 255 * srgb(values[j + 2] * gain) + 0.5; px[4 * p + 3] = 255;
    }
    g.putImageData(frame, 0, 0);
    toned.set(key, { canvas, ev: state.ev });
    return canvas;
  }
  const canvas = document.getElementById('ab-canvas'), ctx = canvas.getContext('2d');
  function levelFor(zoom) { return Math.max(0, Math.min(LAST, Math.floor(Math.log2(1 / zoom) + 1e-9))); }
  function visibleTiles(k) {  // the level's tiles that meet the viewport
    const L = pyr.levels[k], s = L.scale * state.zoom * T, out = [];
    const c0 = Math.max(0, Math.floor(-state.x / s)), c1 = Math.min(L.columns - 1, Math.floor((canvas.width - state.x) / s));
    const r0 = Math.max(0, Math.floor(-state.y / s)), r1 = Math.min(L.rows - 1, Math.floor((canvas.height - state.y) / s));
    for (let r = r0; r <= r1; r++) for (let c = c0; c <= c1; c++) out.push(r * L.columns + c);
    return out;
  }
  function drawLevel(name, k, tiles) {  // true when every tile was ready
    const s = pyr.levels[k].scale * state.zoom;
    let complete = true;
    ctx.imageSmoothingEnabled = s < 1;
    for (const i of tiles) {
      const tile = tonedTile(name, k, i), [c, r] = tileRect(k, i);
      if (tile) ctx.drawImage(tile, state.x + c * T * s, state.y + r * T * s, tile.width * s, tile.height * s);
      else complete = false;
    }
    return complete;
  }
  function draw() {
    const k = levelFor(state.zoom), wanted = visibleTiles(k), overview = visibleTiles(LAST), keep = new Set();
    for (const name of data.order) {  // every image's view, so an A/B flip has its tiles ready
      for (const i of overview) { load(name, LAST, i); keep.add(name + '/' + LAST + '/' + i); }
      for (const i of wanted) { load(name, k, i); keep.add(name + '/' + k + '/' + i); }
    }
    evict(keep);
    ctx.fillStyle = '#000'; ctx.fillRect(0, 0, canvas.width, canvas.height);
    if (k !== LAST) drawLevel(state.showing, LAST, overview);  // beneath the finer tiles while they load
    viewer.complete = drawLevel(state.showing, k, wanted);
    viewer.draws++; viewer.drawnAt = performance.now();  // ms since navigation: the benchmark's first paint
    document.getElementById('ab-label').textContent = state.showing;
    document.getElementById('ev-value').textContent = state.ev.toFixed(1) + ' EV';
  }
  function schedule() {
    if (viewer.queued) return;
    viewer.queued = true;
    requestAnimationFrame(() => { viewer.queued = false; draw(); });
  }
  function flip() {
    const i = data.order.indexOf(state.showing);
    state.showing = data.order[(i + 1) % data.order.length];
    draw();
  }
  const stages = Array.from(document.querySelectorAll('.stage'));
  function applyView() {
    for (const s of stages) s.style.transform = `translate(${state.x}px, ${state.y}px) scale(${state.zoom})`;
    schedule();
  }
  function zoomAt(factor, cx, cy) {
    const z = Math.min(64, Math.max(Math.min(0.25, data.fit / 2), state.zoom * factor)), k = z / state.zoom;
    state.x = cx - k * (cx - state.x); state.y = cy - k * (cy - state.y); state.zoom = z; applyView();
  }
  for (const vp of document.querySelectorAll('.viewport')) {
    vp.addEventListener('wheel', ev => {
      ev.preventDefault();
      const r = vp.getBoundingClientRect();
      zoomAt(ev.deltaY < 0 ? 1.25 : 0.8, ev.clientX - r.left, ev.clientY - r.top);
    }, { passive: false });
    let drag = null;
    vp.addEventListener('mousedown', ev => { drag = { x: ev.clientX - state.x, y: ev.clientY - state.y }; });
    window.addEventListener('mouseup', () => { drag = null; });
    window.addEventListener('mousemove', ev => {
      if (drag) { state.x = ev.clientX - drag.x; state.y = ev.clientY - drag.y; applyView(); }
    });
  }
  document.getElementById('flip').addEventListener('click', flip);
  document.getElementById('zoom-in').addEventListener('click', () => zoomAt(1.25, 0, 0));
  document.getElementById('zoom-out').addEventListener('click', () => zoomAt(0.8, 0, 0));
  document.getElementById('zoom-fit').addEventListener('click', () => {
    state.zoom = data.fit; state.x = 0; state.y = 0; applyView();
  });
  document.getElementById('zoom-reset').addEventListener('click', () => {  // 1:1 about the viewport's centre
    const cx = canvas.width / 2, cy = canvas.height / 2;
    state.x = cx - (cx - state.x) / state.zoom; state.y = cy - (cy - state.y) / state.zoom; state.zoom = 1; applyView();
  });
  const slider = document.getElementById('exposure');
  slider.value = state.ev;
  slider.addEventListener('input', () => { state.ev = parseFloat(slider.value); draw(); });
  window.addEventListener('keydown', ev => {
    if (ev.target && ev.target.tagName === 'INPUT') return;
    if (ev.key === 'f' || ev.key === 'F' || ev.key === ' ') { ev.preventDefault(); flip(); }
  });
  const select = document.getElementById('map-select');
  const mapImg = document.getElementById('map-img');
  function showMap() {
    const m = data.maps[select.value];
    mapImg.src = document.getElementById('map-src-' + select.value).getAttribute('src');
    document.getElementById('map-legend').textContent = m.legend;
  }
  if (select) { select.addEventListener('change', showMap); showMap(); }
  const overlay = document.getElementById('fringe-overlay'), toggle = document.getElementById('overlay-toggle');
  function flipOverlay() {
    const on = overlay.style.display === 'none';
    overlay.style.display = on ? 'block' : 'none';
    toggle.setAttribute('aria-pressed', on ? 'true' : 'false');
  }
  if (overlay && toggle) {
    toggle.addEventListener('click', flipOverlay);
    window.addEventListener('keydown', ev => {
      if (ev.target && ev.target.tagName === 'INPUT') return;
      if (ev.key === 'o' || ev.key === 'O') flipOverlay();
    });
  }
  applyView(); draw();
})();
"""


def view_size(width: int, height: int) -> tuple[int, int, float]:
    """The image panels' size in CSS pixels and the zoom that fits the image in them (1 when it fits at 1:1)."""
    fit = min(1.0, MAX_VIEW[0] / width, MAX_VIEW[1] / height)
    return max(1, round(width * fit)), max(1, round(height * fit)), fit


def render_page(*, title: str, pyramid: dict, exposure_ev: float,
                maps: dict[str, dict], sections: list[tuple[str, str]], notes: list[str], errors: list[str],
                verdict: str = "", overlay: str = "", overlay_legend: str = "") -> str:
    """The whole page. ``pyramid``: the images as reports.page.tiles.pyramid wrote them (photo
    first); ``maps``: name -> {"uri": data URI, "legend": text}, drawn over the image's full size
    whatever their resolution; ``sections``: (heading, trusted HTML built with table());
    ``verdict``: the scene fit's block (trusted HTML, reports.page.verdict_block), first on the page;
    ``overlay``: an inline SVG over the A/B image (trusted, reports.page.fringe_overlay), with a toggle."""
    width, height = pyramid["levels"][0]["width"], pyramid["levels"][0]["height"]
    view_w, view_h, fit = view_size(width, height)
    data = {"width": width, "height": height, "exposure_ev": exposure_ev, "order": list(pyramid["tiles"]), "fit": fit,
            "pyramid": pyramid, "maps": {name: {"legend": m["legend"]} for name, m in maps.items()}}
    map_sources = "".join(f"<img id='map-src-{html.escape(name)}' src='{m['uri']}' alt='{html.escape(name)}' hidden>"
                          for name, m in maps.items())
    options = "".join(f"<option value='{html.escape(name)}'>{html.escape(name)}</option>" for name in maps)
    viewport = f"class='viewport' style='width:{view_w}px;height:{view_h}px'"
    stage = f"class='stage' style='width:{width}px;height:{height}px'"
    map_panel = (f"""<div class="panel"><div class="title">error map:
      <select id="map-select">{options}</select> <span id="map-legend"></span>
      <span class="legend"><img alt="colour scale" src="{legend_data_uri()}"></span></div>
      <div {viewport}><div {stage}>
      <img id="map-img" alt="error map" width="{width}" height="{height}"></div></div></div>"""
                 if maps else "")
    note_html = "".join(f"<div class='note'>{html.escape(n)}</div>" for n in notes)
    error_html = "".join(f"<div class='error'>{html.escape(e)}</div>" for e in errors)
    body_sections = "".join(f"<h2>{html.escape(h)}</h2>{content}" for h, content in sections)
    overlay_bar = (f"<div class='bar'><button id='overlay-toggle' aria-pressed='false' title='O key'>fringe overlay"
                   f"</button> <span>{html.escape(overlay_legend)}</span></div>" if overlay else "")
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy"
 content="default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'">
<title>{html.escape(title)}</title><style>{STYLE}</style></head>
<body>
<h1>{html.escape(title)}</h1>
{verdict}{error_html}{note_html}
<div class="bar">
  <button id="flip" title="A/B flip (F or space)">A/B flip</button> showing <b id="ab-label"></b>
  <label>exposure <input id="exposure" type="range" min="-12" max="12" step="0.1"></label> <span id="ev-value"></span>
  <button id="zoom-in">+</button><button id="zoom-out">&minus;</button><button id="zoom-fit">fit</button><button
   id="zoom-reset" title="one image pixel per screen pixel">1:1</button>
  <span>(wheel: zoom, drag: pan; the panels move together)</span>
</div>
{overlay_bar}
<div class="panels">
  <div class="panel"><div class="title">photo / render (linear camera RGB, one display transform; {width} x {height})</div>
    <div {viewport}><canvas id="ab-canvas" width="{view_w}" height="{view_h}"></canvas>
    <div {stage}>{overlay}</div></div></div>
  {map_panel}
</div>
{map_sources}
{body_sections}
<script type="application/json" id="report-data">{_json_for_script(data)}</script>
<script>{SCRIPT}</script>
</body></html>
"""
