"""The report's images as a pyramid of compressed tiles: a photo of any size makes a page of bounded size.

Level 0 is the display image (linear sRGB) at full resolution; each next level halves it
(2 x 2 box average in linear light, the mean of what the pixels saw) until a level holds no
more than OVERVIEW_PIXELS. That coarsest level, the whole image when the image is small, is
stored exactly: float16, byte-shuffled and deflate-compressed (zlib, RFC 1950), decoded in
the page by the browser's DecompressionStream. The finer levels exist only for large photos
and are lossy: each pixel's linear value log-encoded to 8 bits over the page's range (code 0
is black; codes 1-255 span [lo, hi] stops evenly, LOG_STOPS at most), as JPEG without chroma
subsampling (a colour fringe one pixel wide keeps its colour), at the best quality whose
tiles fit the page's budget, decoded by the browser's image decoder. The exposure slider
acts on the decoded linear values at every level.

Tiles are TILE x TILE level pixels, row-major; the page loads the tiles of the level the zoom
calls for and draws the overview beneath them while they load (reports.page.html).
"""

from __future__ import annotations

import base64
import io
import zlib
from dataclasses import dataclass

import numpy as np
from PIL import Image

TILE = 512
OVERVIEW_PIXELS = 600_000  # 6000 x 4000 -> 750 x 500 at level 3; every draft (640 x 480) image is one exact level
LOG_STOPS = 16.0  # the widest range of the lossy levels' code: 254 codes over 16 stops is a 4.5 % step
JPEG_QUALITIES = (95, 90, 85, 80, 75, 70, 60, 50)  # tried best first: the lossy levels take the best that fits
TILE_BUDGET = 18_000_000  # base64 characters for all the page's tiles: 24 MP photo and render, with 7 MB to spare
SAMPLE_TILES = 12  # full-resolution tiles per image encoded to estimate the lossy levels' size


@dataclass(frozen=True)
class LogCode:
    """8-bit code c <-> linear x: c = 0 is x <= 0; x = 2^(lo + (c - 1) (hi - lo) / 254) otherwise."""

    lo: float
    hi: float

    @classmethod
    def spanning(cls, images: list[np.ndarray]) -> LogCode:
        """The range of the page's images: up to their brightest value, down LOG_STOPS or to the
        0.1th percentile of their positive values, whichever is higher."""
        positive = np.concatenate([im[im > 0][:: max(1, im.size // 2_000_000)] for im in images])
        if positive.size == 0:  # black images: any range draws them black
            positive = np.ones(1, np.float32)
        hi = float(np.log2(positive.max()))
        lo = max(hi - LOG_STOPS, float(np.log2(np.percentile(positive, 0.1))))
        return cls(lo, max(hi, lo + 1.0))

    def encode(self, linear: np.ndarray) -> np.ndarray:
        stops = np.log2(np.maximum(linear, 2.0 ** (self.lo - 1)))
        codes = 1.0 + np.rint((np.clip(stops, self.lo, self.hi) - self.lo) * 254.0 / (self.hi - self.lo))
        return np.where(linear > 2.0 ** (self.lo - 1), codes, 0).astype(np.uint8)

    def decode(self, codes: np.ndarray) -> np.ndarray:
        table = np.concatenate([[0.0], 2.0 ** (self.lo + np.arange(255) * (self.hi - self.lo) / 254.0)])
        return table[codes].astype(np.float32)


def halved(image: np.ndarray) -> np.ndarray:
    """The next level: 2 x 2 box average (an odd last row or column averaged with itself)."""
    h, w = image.shape[:2]
    padded = np.pad(image, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
    return padded.reshape((h + 1) // 2, 2, (w + 1) // 2, 2, -1).mean(axis=(1, 3), dtype=np.float32)


def level_count(width: int, height: int) -> int:
    """How many levels a width x height image has: down to the first with at most OVERVIEW_PIXELS."""
    count = 1
    while width * height > OVERVIEW_PIXELS:
        width, height, count = (width + 1) // 2, (height + 1) // 2, count + 1
    return count


def overview_of(values: np.ndarray) -> np.ndarray:
    """A per-pixel map (H, W) or (H, W, C) at the overview level's size, box-averaged (nan-aware)."""
    levels = level_count(values.shape[1], values.shape[0])
    image = values[..., None] if values.ndim == 2 else values
    for _ in range(levels - 1):
        finite = np.isfinite(image)
        sums, counts = halved(np.where(finite, image, 0.0)), halved(finite.astype(np.float32))
        with np.errstate(invalid="ignore", divide="ignore"):
            image = np.where(counts > 0, sums / np.maximum(counts, 1e-12), np.nan).astype(np.float32)
    return image[..., 0] if values.ndim == 2 else image


def _tiles(image: np.ndarray) -> list[np.ndarray]:
    h, w = image.shape[:2]
    return [image[r:r + TILE, c:c + TILE] for r in range(0, h, TILE) for c in range(0, w, TILE)]


def _exact(tile: np.ndarray) -> str:
    """float16, its low bytes then its high bytes (the shuffle: the high bytes, sign, exponent and top of the
    mantissa, vary slowly and deflate well; 25 % smaller on a noisy photo), zlib-compressed, base64."""
    halves = np.ascontiguousarray(tile, dtype="<f2").view(np.uint8).reshape(-1, 2)
    return base64.b64encode(zlib.compress(halves.T.tobytes(), 9)).decode("ascii")


def _lossy(tile: np.ndarray, code: LogCode, quality: int) -> str:
    buffer = io.BytesIO()
    Image.fromarray(code.encode(tile)).save(buffer, format="JPEG", quality=quality, subsampling=0)
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def lossy_quality(levels: dict[str, list[np.ndarray]], code: LogCode, budget: int) -> int:
    """The highest of JPEG_QUALITIES whose lossy tiles fit in ``budget`` characters, estimated
    from up to SAMPLE_TILES full-resolution tiles per image (noise, which costs most, is finest
    there, so the estimate errs high); the lowest where none fits."""
    lossy_pixels = sum(level.shape[0] * level.shape[1] for stack in levels.values() for level in stack[:-1])
    finest = [_tiles(stack[0]) for stack in levels.values()]
    samples = [t for tiles in finest for t in tiles[:: max(1, len(tiles) // SAMPLE_TILES)]]
    sampled_pixels = sum(t.shape[0] * t.shape[1] for t in samples)
    for quality in JPEG_QUALITIES:
        characters = sum(len(_lossy(t, code, quality)) for t in samples)
        if characters / sampled_pixels * lossy_pixels <= budget:
            return quality
    return JPEG_QUALITIES[-1]


def pyramid(images: dict[str, np.ndarray], budget: int = TILE_BUDGET) -> dict:
    """The page's ``pyramid`` entry for images of one size (name -> (H, W, 3) linear): the
    levels' sizes and codecs, the log code and JPEG quality of the lossy levels (the highest
    whose tiles fit ``budget`` characters with the exact level's), and per image per level its
    tiles (base64 strings, row-major)."""
    first = next(iter(images.values()))
    count = level_count(first.shape[1], first.shape[0])
    levels = {name: [np.asarray(image, np.float32)] for name, image in images.items()}
    for stack in levels.values():
        while len(stack) < count:
            stack.append(halved(stack[-1]))
    code = LogCode.spanning(list(images.values()))
    tiles: dict[str, list[list[str]]] = {name: [[] for _ in range(count)] for name in images}
    for name, stack in levels.items():
        tiles[name][-1] = [_exact(t) for t in _tiles(stack[-1])]
    exact_characters = sum(len(t) for name in tiles for t in tiles[name][-1])
    quality = lossy_quality(levels, code, budget - exact_characters) if count > 1 else None
    for name, stack in levels.items():
        for k in range(count - 1):
            assert quality is not None  # there are lossy levels
            tiles[name][k] = [_lossy(t, code, quality) for t in _tiles(stack[k])]
    sizes = [(level.shape[1], level.shape[0]) for level in next(iter(levels.values()))]
    described = [{"scale": 2 ** k, "width": w, "height": h, "columns": -(-w // TILE), "rows": -(-h // TILE),
                  "codec": "float16-shuffled-deflate" if k == count - 1 else "log8-jpeg"} for k, (w, h) in enumerate(sizes)]
    return {"tile": TILE, "log_code": {"lo": code.lo, "hi": code.hi}, "jpeg_quality": quality, "tiles": tiles,
            "levels": described}
