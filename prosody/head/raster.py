"""A z-buffered triangle rasteriser with per-pixel shading, compiled by Numba: the head's CPU renderer.

Two passes: the first keeps, for every pixel, the nearest triangle and the pixel centre's barycentric
coordinates in it; the second shades each covered pixel once, interpolating the vertex normals and colours
(Phong shading: two directional lights, an ambient term and a weak specular highlight, lit from both sides
so the inside of the mouth is lit like a surface). Everything runs on the CPU, in one thread, and the result
is the same on every machine for the same input (no GPU, no driver).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .view import AMBIENT, FILL, KEY, SHININESS_DOUBLINGS, SPECULAR, light_directions




@njit(cache=True, nogil=True, parallel=True)
def _cover(screen, triangles, nearest, weights, depth):  # pragma: no cover - compiled
    height, width = depth.shape
    # horizontal bands, one per task: each draws every triangle clipped to its rows (no two write one pixel)
    n_bands = 16
    for band in prange(n_bands):
        band_top = band * height // n_bands
        band_bottom = (band + 1) * height // n_bands - 1
        for py in range(band_top, band_bottom + 1):
            for px in range(depth.shape[1]):
                depth[py, px] = np.inf
                nearest[py, px] = -1
        _cover_band(screen, triangles, nearest, weights, depth, band_top, band_bottom)


@njit(cache=True, nogil=True)
def _cover_band(screen, triangles, nearest, weights, depth, band_top, band_bottom):  # pragma: no cover
    width = depth.shape[1]
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        y0, y1, y2 = screen[a, 1], screen[b, 1], screen[c, 1]
        if max(y0, y1, y2) < band_top or min(y0, y1, y2) > band_bottom + 1:
            continue
        x0, z0 = screen[a, 0], screen[a, 2]
        x1, z1 = screen[b, 0], screen[b, 2]
        x2, z2 = screen[c, 0], screen[c, 2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-9 or z0 <= 0 or z1 <= 0 or z2 <= 0:
            continue
        left = max(int(np.floor(min(x0, x1, x2))), 0)
        right = min(int(np.ceil(max(x0, x1, x2))), width - 1)
        top = max(int(np.floor(min(y0, y1, y2))), band_top)
        bottom = min(int(np.ceil(max(y0, y1, y2))), band_bottom)
        if top > bottom:
            continue
        inverse = 1.0 / area
        for py in range(top, bottom + 1):
            cy = py + 0.5
            for px in range(left, right + 1):
                cx = px + 0.5
                w0 = ((x1 - cx) * (y2 - cy) - (x2 - cx) * (y1 - cy)) * inverse
                if w0 < 0:
                    continue
                w1 = ((x2 - cx) * (y0 - cy) - (x0 - cx) * (y2 - cy)) * inverse
                if w1 < 0:
                    continue
                w2 = 1.0 - w0 - w1
                if w2 < 0:
                    continue
                z = w0 * z0 + w1 * z1 + w2 * z2
                if z < depth[py, px]:
                    depth[py, px] = z
                    nearest[py, px] = t
                    weights[py, px, 0] = w0
                    weights[py, px, 1] = w1


@njit(cache=True, nogil=True, parallel=True)
def _shade(triangles, normals, colors, nearest, weights, image, lights, strengths,
           background):  # pragma: no cover - compiled
    height, width = nearest.shape
    for py in prange(height):
        for px in range(width):
            t = nearest[py, px]
            if t < 0:
                for channel in range(3):
                    image[py, px, channel] = background[channel]
                continue
            a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
            w0, w1 = weights[py, px, 0], weights[py, px, 1]
            w2 = 1.0 - w0 - w1
            nx = w0 * normals[a, 0] + w1 * normals[b, 0] + w2 * normals[c, 0]
            ny = w0 * normals[a, 1] + w1 * normals[b, 1] + w2 * normals[c, 1]
            nz = w0 * normals[a, 2] + w1 * normals[b, 2] + w2 * normals[c, 2]
            norm = np.sqrt(nx * nx + ny * ny + nz * nz)
            if norm > 0:
                nx, ny, nz = nx / norm, ny / norm, nz / norm
            if nz < 0:  # lit from both sides
                nx, ny, nz = -nx, -ny, -nz
            diffuse = strengths[2]
            specular = 0.0
            for k in range(2):
                lx, ly, lz = lights[k, 0], lights[k, 1], lights[k, 2]
                lambert = nx * lx + ny * ly + nz * lz
                if lambert > 0:
                    diffuse += strengths[k] * lambert
                    hx, hy, hz = lx, ly, lz + 1.0
                    hn = np.sqrt(hx * hx + hy * hy + hz * hz)
                    cosine = (nx * hx + ny * hy + nz * hz) / hn
                    if cosine > 0:
                        for _ in range(SHININESS_DOUBLINGS):  # cosine ** 32
                            cosine *= cosine
                        specular += strengths[k] * cosine
            for channel in range(3):
                albedo = w0 * colors[a, channel] + w1 * colors[b, channel] + w2 * colors[c, channel]
                value = albedo * diffuse + strengths[3] * specular
                image[py, px, channel] = min(value, 1.0)


@njit(cache=True, nogil=True, parallel=True)
def _downsample(image, factor, out):  # pragma: no cover - compiled
    height, width = out.shape[0], out.shape[1]
    scale = 255.0 / (factor * factor)
    for py in prange(height):
        for px in range(width):
            for channel in range(3):
                total = 0.0
                for dy in range(factor):
                    for dx in range(factor):
                        total += image[py * factor + dy, px * factor + dx, channel]
                out[py, px, channel] = np.uint8(min(total * scale + 0.5, 255.0))


def downsample(image: np.ndarray, factor: int) -> np.ndarray:
    """Box-average ``factor`` x ``factor`` blocks of a float image in 0..1 into an RGB uint8 image."""
    height, width = image.shape[0] // factor, image.shape[1] // factor
    out = np.empty((height, width, 3), np.uint8)
    _downsample(image, factor, out)
    return out


_LIGHTS = light_directions()
_STRENGTHS = np.array([KEY, FILL, AMBIENT, SPECULAR])


class Canvas:
    """The buffers one image size needs (depth, nearest triangle, barycentric weights, colour), kept between
    frames."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.depth = np.empty((height, width), np.float32)
        self.nearest = np.empty((height, width), np.int32)
        self.weights = np.empty((height, width, 2), np.float32)
        self.image = np.empty((height, width, 3), np.float32)


def rasterise(screen: np.ndarray, triangles: np.ndarray, normals: np.ndarray, colors: np.ndarray, *,
              width: int, height: int, background: tuple[float, float, float],
              canvas: Canvas | None = None) -> np.ndarray:
    """Draw a triangle mesh; returns float32 (height, width, 3) in 0..1 (the canvas's own image buffer).

    Parameters
    ----------
    screen : float (n, 3)
        Vertex pixel coordinates (x right, y down, from the top-left corner) and depth (> 0, smaller is nearer).
    triangles : int32 (m, 3)
        Vertex indices.
    normals : float (n, 3)
        Vertex normals in camera axes (x right, y up, z towards the viewer).
    colors : float (n, 3)
        Vertex albedo, 0..1.
    width, height : int
        Image size in pixels.
    background : (r, g, b) in 0..1
        Where no triangle is.
    canvas : Canvas, optional
        Buffers of this size to draw in (reused between frames); a new one by default.
    """
    if canvas is None or (canvas.width, canvas.height) != (width, height):
        canvas = Canvas(width, height)
    _cover(np.ascontiguousarray(screen, np.float64), np.ascontiguousarray(triangles, np.int32), canvas.nearest,
           canvas.weights, canvas.depth)
    _shade(np.ascontiguousarray(triangles, np.int32), np.ascontiguousarray(normals, np.float64),
           np.ascontiguousarray(colors, np.float64), canvas.nearest, canvas.weights, canvas.image, _LIGHTS,
           _STRENGTHS, np.asarray(background, np.float64))
    return canvas.image
