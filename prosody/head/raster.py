"""A z-buffered triangle rasteriser with per-pixel shading, compiled by Numba: the head's CPU renderer.

Two passes: the first keeps, for every pixel, the nearest triangle and the pixel centre's barycentric
coordinates in it; the second shades each covered pixel once (or takes its colour from a texture, for the
photo head), interpolating the vertex normals and colours
(Phong shading: two directional lights, an ambient term and a weak specular highlight, lit from both sides
so the inside of the mouth is lit like a surface). Everything runs on the CPU, the rows of a frame spread over
its cores (Numba's ``prange``), and the result is the same on every machine for the same input (no GPU, no
driver).

Numba's OpenMP workers wait for work asleep (``OMP_WAIT_POLICY=PASSIVE`` unless the environment says
otherwise): a frame is drawn as fast, and on a busy machine the waiting threads no longer spin on the cores
other programs need (30 photo frames: 0.36 s of processor time instead of 0.43 s on a quiet machine, 0.42 s
instead of 0.65 s beside two other renderers; the time on the clock the same or less).
"""

from __future__ import annotations

import os
import signal
import threading

# read by OpenMP when Numba first starts its workers (the first frame), so set before any is drawn
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import numpy as np  # noqa: E402 - after the workers' wait policy
from numba import njit, prange  # noqa: E402

from .view import AMBIENT, FILL, KEY, SHININESS_DOUBLINGS, SPECULAR, light_directions


@njit(cache=True, nogil=True, parallel=True)
def _cover(screen, triangles, nearest, weights, depth, row0, column0):  # pragma: no cover - compiled
    """Fill the buffers (a window of the samples whose corner is sample row0, column0; the screen's
    coordinates are the whole image's, so a window's samples are those of the whole, bit for bit)."""
    height, width = depth.shape
    # horizontal bands, one per task: each draws every triangle clipped to its rows (no two write one pixel);
    # each band looks at every triangle, so a small window (the mouth's) has few bands
    n_bands = max(1, min(16, height // 16))
    for band in prange(n_bands):
        band_top = band * height // n_bands
        band_bottom = (band + 1) * height // n_bands - 1
        for py in range(band_top, band_bottom + 1):
            for px in range(depth.shape[1]):
                depth[py, px] = np.inf
                nearest[py, px] = -1
        _cover_band(screen, triangles, nearest, weights, depth, band_top, band_bottom, row0, column0)


@njit(cache=True, nogil=True)
def _cover_band(screen, triangles, nearest, weights, depth, band_top, band_bottom, row0,
                column0):  # pragma: no cover
    width = depth.shape[1]
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        y0, y1, y2 = screen[a, 1], screen[b, 1], screen[c, 1]
        if max(y0, y1, y2) < band_top + row0 or min(y0, y1, y2) > band_bottom + row0 + 1:
            continue
        x0, z0 = screen[a, 0], screen[a, 2]
        x1, z1 = screen[b, 0], screen[b, 2]
        x2, z2 = screen[c, 0], screen[c, 2]
        area = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
        if abs(area) < 1e-9 or z0 <= 0 or z1 <= 0 or z2 <= 0:
            continue
        left = max(int(np.floor(min(x0, x1, x2))) - column0, 0)
        right = min(int(np.ceil(max(x0, x1, x2))) - column0, width - 1)
        top = max(int(np.floor(min(y0, y1, y2))) - row0, band_top)
        bottom = min(int(np.ceil(max(y0, y1, y2))) - row0, band_bottom)
        if top > bottom:
            continue
        inverse = 1.0 / area
        # the barycentric weights are linear along a row: w_i = slope_i * cx + offset_i; each row's span is
        # where all three are >= 0
        slope0, slope1 = (y1 - y2) * inverse, (y2 - y0) * inverse
        slope2 = -(slope0 + slope1)
        for py in range(top, bottom + 1):
            cy = py + row0 + 0.5
            offset0 = (x1 * (y2 - cy) - x2 * (y1 - cy)) * inverse
            offset1 = (x2 * (y0 - cy) - x0 * (y2 - cy)) * inverse
            offset2 = 1.0 - offset0 - offset1
            low, high = left + column0 + 0.5, right + column0 + 0.5
            empty = False
            for slope, offset in ((slope0, offset0), (slope1, offset1), (slope2, offset2)):
                if slope > 0:
                    low = max(low, -offset / slope)
                elif slope < 0:
                    high = min(high, -offset / slope)
                elif offset < 0:
                    empty = True
            if empty or low > high:
                continue
            first = max(left, int(np.ceil(low - 0.5)) - column0)
            last = min(right, int(np.floor(high - 0.5)) - column0)
            for px in range(first, last + 1):
                cx = px + column0 + 0.5
                w0 = slope0 * cx + offset0
                w1 = slope1 * cx + offset1
                w2 = 1.0 - w0 - w1
                if w0 < 0 or w1 < 0 or w2 < 0:
                    continue
                z = w0 * z0 + w1 * z1 + w2 * z2
                if z < depth[py, px]:
                    depth[py, px] = z
                    nearest[py, px] = t
                    weights[py, px, 0] = w0
                    weights[py, px, 1] = w1


@njit(cache=True, nogil=True, inline="always")
def _shade_sample(t, w0, w1, triangles, normals, colors, lights, strengths, rgb):  # pragma: no cover
    """Add the shaded colour of the point (w0, w1) of triangle t to ``rgb``."""
    a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
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
            cosine = (nx * hx + ny * hy + nz * hz) / np.sqrt(hx * hx + hy * hy + hz * hz)
            if cosine > 0:
                for _ in range(SHININESS_DOUBLINGS):  # cosine ** 32
                    cosine *= cosine
                specular += strengths[k] * cosine
    for channel in range(3):
        albedo = w0 * colors[a, channel] + w1 * colors[b, channel] + w2 * colors[c, channel]
        rgb[channel] += min(albedo * diffuse + strengths[3] * specular, 1.0)


_LIGHTS = light_directions()
#: What an untextured mesh passes for its texture coordinates and texture (never read).
_NO_UV, _NO_TEXTURE = np.zeros((1, 2)), np.zeros((1, 1, 3), np.float32)
_STRENGTHS = np.array([KEY, FILL, AMBIENT, SPECULAR])


_workers_started = False


def _start_workers() -> None:
    """Start Numba's worker threads with Ctrl-C and SIGTERM blocked in them (they inherit the mask of the
    thread that starts them), so that those signals always reach the main thread, where Python handles them
    at once; a worker thread receiving one would delay the interrupt until it gets to run."""
    global _workers_started
    if _workers_started:
        return
    if threading.current_thread() is threading.main_thread():
        masked = {signal.SIGINT, signal.SIGTERM}
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, masked)
        try:
            _cover(np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros((16, 16), np.int32),
                   np.zeros((16, 16, 2), np.float32), np.zeros((16, 16), np.float32), 0, 0)
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)
    _workers_started = True


class Canvas:
    """The buffers one image size needs (depth, nearest triangle and barycentric weights per sample), kept
    between frames."""

    def __init__(self, width: int, height: int, factor: int) -> None:
        self.width, self.height, self.factor = width, height, factor
        samples = (height * factor, width * factor)
        self.depth = np.empty(samples, np.float32)
        self.nearest = np.empty(samples, np.int32)
        self.weights = np.empty((*samples, 2), np.float32)
        self._plain: tuple[tuple[float, ...], np.ndarray] | None = None

    def plain(self, color: tuple[float, float, float]) -> np.ndarray:
        """A background image of one colour at this canvas's size (kept for the next frame)."""
        key = tuple(float(c) for c in color)
        if self._plain is None or self._plain[0] != key:
            self._plain = (key, np.broadcast_to(np.asarray(key, np.float32), (self.height, self.width, 3)).copy())
        return self._plain[1]


def rasterise(screen: np.ndarray, triangles: np.ndarray, normals: np.ndarray, colors: np.ndarray, *,
              width: int, height: int, background: tuple[float, float, float], factor: int = 1,
              canvas: Canvas | None = None) -> np.ndarray:
    """Draw a triangle mesh; returns RGB uint8 (height, width, 3).

    Parameters
    ----------
    screen : float (n, 3)
        Vertex sample coordinates (x right, y down, from the top-left corner, in pixels x ``factor``) and depth
        (> 0, smaller is nearer).
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
    factor : int >= 1
        Samples per pixel along each axis (2: four samples per pixel, box-averaged: smooth edges).
    canvas : Canvas, optional
        Buffers of this size to draw in (reused between frames); new ones by default.
    """
    if canvas is None or (canvas.width, canvas.height, canvas.factor) != (width, height, factor):
        canvas = Canvas(width, height, factor)
    return rasterise_textured(screen, triangles, normals, colors, _NO_UV, np.zeros(len(triangles), np.bool_),
                              _NO_TEXTURE, canvas.plain(background), factor=factor, canvas=canvas)


@njit(cache=True, nogil=True, inline="always")
def lit(value, gain):  # pragma: no cover - compiled
    """A texture's value (0..1) under a light ``gain``: darker in proportion below 1; above 1 each value moves
    towards white by what it would gain, as a share of the room it has left (``1 - exp(-x)`` of it), so a
    bright photo brightened keeps its detail and never clips (a value of 0.9 at a gain of 1.4 reads 0.997, not
    1.26 cut to 1; dark values gain as they would linearly)."""
    if gain <= 1.0 or value >= 1.0:
        return min(value * gain, 1.0)
    room = 1.0 - value
    return value + room * (1.0 - np.exp(-(gain - 1.0) * value / room))


@njit(cache=True, nogil=True, inline="always")
def _texel(texture, u, v, rgb, gain0, gain1, gain2, behind):  # pragma: no cover - compiled
    """Add the bilinear sample of ``texture`` (h, w, 3 or 4; 0..1) at pixel coordinates (u, v), times a gain
    per channel. A fourth channel is the texture's coverage: where it is below 1, ``behind`` (the background's
    colour at that pixel) shows through."""
    height, width = texture.shape[0], texture.shape[1]
    x = min(max(u - 0.5, 0.0), width - 1.0)
    y = min(max(v - 0.5, 0.0), height - 1.0)
    x0, y0 = int(x), int(y)
    x1, y1 = min(x0 + 1, width - 1), min(y0 + 1, height - 1)
    fx, fy = x - x0, y - y0
    cover = 1.0
    if texture.shape[2] > 3:
        top = texture[y0, x0, 3] * (1 - fx) + texture[y0, x1, 3] * fx
        bottom = texture[y1, x0, 3] * (1 - fx) + texture[y1, x1, 3] * fx
        cover = top * (1 - fy) + bottom * fy
    for channel in range(3):
        top = texture[y0, x0, channel] * (1 - fx) + texture[y0, x1, channel] * fx
        bottom = texture[y1, x0, channel] * (1 - fx) + texture[y1, x1, channel] * fx
        gain = gain0 if channel == 0 else (gain1 if channel == 1 else gain2)
        rgb[channel] += cover * lit(top * (1 - fy) + bottom * fy, gain) + (1 - cover) * behind[channel]


@njit(cache=True, nogil=True, inline="always")
def _paint_sample(t, w0, w1, triangles, normals, colors, uv, textured, texture, lights, strengths,
                  rgb, behind):  # pragma: no cover - compiled
    """Add the colour of the point (w0, w1) of triangle t: where the triangle is textured, the texture times
    the vertex colours (a gain: 1 shows the texture as it is; where the texture's coverage is partial, over
    ``behind``), else its shaded vertex colour."""
    if textured[t]:
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        w2 = 1.0 - w0 - w1
        u = w0 * uv[a, 0] + w1 * uv[b, 0] + w2 * uv[c, 0]
        v = w0 * uv[a, 1] + w1 * uv[b, 1] + w2 * uv[c, 1]
        _texel(texture, u, v, rgb, w0 * colors[a, 0] + w1 * colors[b, 0] + w2 * colors[c, 0],
               w0 * colors[a, 1] + w1 * colors[b, 1] + w2 * colors[c, 1],
               w0 * colors[a, 2] + w1 * colors[b, 2] + w2 * colors[c, 2], behind)
    else:
        _shade_sample(t, w0, w1, triangles, normals, colors, lights, strengths, rgb)


@njit(cache=True, nogil=True, parallel=True)
def _resolve_textured(triangles, normals, colors, uv, textured, texture, nearest, weights, factor, out, lights,
                      strengths, background):  # pragma: no cover - compiled
    """As :func:`_resolve`, with textured triangles and a background image (height, width, 3; 0..1)."""
    height, width = out.shape[0], out.shape[1]
    samples = factor * factor
    for py in prange(height):
        rgb = np.zeros(3)
        for px in range(width):
            top, left = py * factor, px * factor
            first = nearest[top, left]
            uniform = True
            for dy in range(factor):
                for dx in range(factor):
                    if nearest[top + dy, left + dx] != first:
                        uniform = False
            rgb[:] = 0.0
            if uniform and first < 0:
                for channel in range(3):
                    rgb[channel] = background[py, px, channel]
            elif uniform:
                w0 = 0.0
                w1 = 0.0
                for dy in range(factor):
                    for dx in range(factor):
                        w0 += weights[top + dy, left + dx, 0]
                        w1 += weights[top + dy, left + dx, 1]
                _paint_sample(first, w0 / samples, w1 / samples, triangles, normals, colors, uv, textured, texture,
                              lights, strengths, rgb, background[py, px])
            else:
                for dy in range(factor):
                    for dx in range(factor):
                        t = nearest[top + dy, left + dx]
                        if t < 0:
                            for channel in range(3):
                                rgb[channel] += background[py, px, channel]
                        else:
                            _paint_sample(t, weights[top + dy, left + dx, 0], weights[top + dy, left + dx, 1],
                                          triangles, normals, colors, uv, textured, texture, lights, strengths,
                                          rgb, background[py, px])
                for channel in range(3):
                    rgb[channel] /= samples
            for channel in range(3):
                out[py, px, channel] = np.uint8(min(max(rgb[channel], 0.0) * 255.0 + 0.5, 255.0))


def rasterise_textured(screen: np.ndarray, triangles: np.ndarray, normals: np.ndarray, colors: np.ndarray,
                       uv: np.ndarray, textured: np.ndarray, texture: np.ndarray, background: np.ndarray, *,
                       factor: int = 1, canvas: Canvas | None = None,
                       window: tuple[int, int, int, int] | None = None, base: np.ndarray | None = None) -> np.ndarray:
    """Draw a mesh whose triangles are textured or shaded, over a background image; RGB uint8 (h, w, 3).

    Parameters
    ----------
    screen, triangles, normals, colors, factor, canvas
        As :func:`rasterise`.
    uv : float (n, 3) or (n, 2)
        Each vertex's place in ``texture``, in its pixels (x right, y down, from the top-left corner).
    textured : bool (m,)
        The triangles drawn from the texture, times their vertices' ``colors`` (1, 1, 1: as it is, not lit
        again); the others are shaded as by :func:`rasterise`.
    texture : float32 (th, tw, 3) or (th, tw, 4), 0..1
        The image the textured triangles show; a fourth channel is its coverage (1: opaque, 0: the background
        shows through, as at a person's outline).
    background : float32 (height, width, 3), 0..1
        What is seen where no triangle is; its size is the image's.
    window : (top, bottom, left, right), optional
        Draw only these pixel rows and columns (inclusive) and take the rest from ``base``, an earlier frame
        (uint8, height x width x 3) where nothing outside the window has changed.
    """
    height, width = background.shape[:2]
    if canvas is None or (canvas.width, canvas.height, canvas.factor) != (width, height, factor):
        canvas = Canvas(width, height, factor)
    screen = np.ascontiguousarray(screen, np.float64)
    if window is None or base is None:
        top, bottom, left, right = 0, height - 1, 0, width - 1
        out = np.empty((height, width, 3), np.uint8)
    else:
        top, bottom = max(0, int(window[0])), min(height - 1, int(window[1]))
        left, right = max(0, int(window[2])), min(width - 1, int(window[3]))
        out = base.copy()
        if top > bottom or left > right:
            return out
    rows, columns = slice(top * factor, (bottom + 1) * factor), slice(left * factor, (right + 1) * factor)
    nearest, weights = canvas.nearest[rows, columns], canvas.weights[rows, columns]
    triangles = np.ascontiguousarray(triangles, np.int32)
    _start_workers()
    _cover(screen, triangles, nearest, weights, canvas.depth[rows, columns], top * factor, left * factor)
    _resolve_textured(triangles, np.ascontiguousarray(normals, np.float64), np.ascontiguousarray(colors, np.float64),
                      np.ascontiguousarray(uv[:, :2], np.float64), np.ascontiguousarray(textured, np.bool_),
                      np.ascontiguousarray(texture, np.float32), nearest, weights, factor,
                      out[top:bottom + 1, left:right + 1], _LIGHTS, _STRENGTHS,
                      np.ascontiguousarray(background, np.float32)[top:bottom + 1, left:right + 1])
    return out
