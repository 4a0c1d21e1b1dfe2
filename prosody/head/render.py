"""Frames of the head: a FAP frame -> the deformed, turned head -> a perspective view -> an RGB image.

The camera and the lights are those of :mod:`.view` (the browser's too); the image is drawn with
:data:`SUPERSAMPLE` x :data:`SUPERSAMPLE` samples per pixel, box-averaged (smooth edges), frames larger than
:data:`SUPERSAMPLED_PIXELS` with one (their pixels are small enough).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..fap.table import N_FAPS
from .raster import Canvas, rasterise
from .rig import HeadRig, head_rig
from .view import BACKGROUND, CAMERA_DISTANCE_CM, HALF_VIEW_CM, LOOK_AT_Y_CM

SUPERSAMPLE = 2
SUPERSAMPLED_PIXELS = 1920 * 1080


class HeadRenderer:
    """Draws the head of ``rig`` in frames of ``width`` x ``height`` pixels.

    Parameters
    ----------
    width, height : int >= 16
        Image size in pixels; the view's height is fixed (the head fills about 70 % of it), a wider frame
        shows more to the sides.
    rig : HeadRig, optional
        The head (default: the canonical one).
    """

    def __init__(self, width: int, height: int, *, rig: HeadRig | None = None) -> None:
        if not (isinstance(width, (int, np.integer)) and isinstance(height, (int, np.integer))
                and width >= 16 and height >= 16):
            raise ConfigError(f"a head frame needs at least 16 x 16 pixels, got {width!r} x {height!r}")
        self.width, self.height = int(width), int(height)
        self.rig = rig or head_rig()
        mesh = self.rig.mesh
        self.triangles = mesh.triangles
        # a vertex's normal is the sum of its triangles' (area-weighted) normals
        self._corners = mesh.triangles.reshape(-1)
        self._colors = mesh.colors.astype(np.float64)
        self.supersample = SUPERSAMPLE if self.width * self.height <= SUPERSAMPLED_PIXELS else 1
        self._canvas = Canvas(self.width, self.height, self.supersample)
        self._triangles32 = np.ascontiguousarray(mesh.triangles, np.int32)

    def project(self, vertices: np.ndarray, *, scale: int = 1) -> np.ndarray:
        """Pixel x, y (from the top-left corner) and depth of head-axes ``vertices`` (n, 3)."""
        w, h = self.width * scale, self.height * scale
        focal = (h / 2) / (HALF_VIEW_CM / CAMERA_DISTANCE_CM)
        depth = CAMERA_DISTANCE_CM - vertices[:, 2]
        return np.column_stack([w / 2 + focal * vertices[:, 0] / depth,
                                h / 2 - focal * (vertices[:, 1] - LOOK_AT_Y_CM) / depth, depth])

    def normals(self, vertices: np.ndarray) -> np.ndarray:
        t = self.triangles
        face_normals = np.cross(vertices[t[:, 1]] - vertices[t[:, 0]], vertices[t[:, 2]] - vertices[t[:, 0]])
        n = self.rig.mesh.n_vertices
        repeated = np.repeat(face_normals, 3, axis=0)
        summed = np.column_stack([np.bincount(self._corners, weights=repeated[:, k], minlength=n) for k in range(3)])
        return summed / np.maximum(np.linalg.norm(summed, axis=1, keepdims=True), 1e-12)

    def render_vertices(self, vertices: np.ndarray) -> np.ndarray:
        """RGB uint8 (height, width, 3) of the head with its vertices at ``vertices``."""
        s = self.supersample
        return rasterise(self.project(vertices, scale=s), self._triangles32, self.normals(vertices), self._colors,
                         width=self.width, height=self.height, background=BACKGROUND, factor=s,
                         canvas=self._canvas)

    def render(self, values: np.ndarray) -> np.ndarray:
        """RGB uint8 (height, width, 3) of one frame's FAP values (68, FAP units; NaN and 0 are neutral)."""
        values = np.asarray(values, float)
        if values.shape != (N_FAPS,):
            raise ConfigError(f"a head frame takes {N_FAPS} FAP values, got shape {values.shape}")
        return self.render_vertices(self.rig.deform(values))
