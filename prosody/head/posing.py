"""The photo head's geometry of one frame, compiled by Numba: where every drawn vertex is, its normal, and the
box of what can have moved.

:class:`prosody.head.photo.PhotoRenderer` poses the face in the head's axes (the rest shape plus each FAP's
field times its value), carries it into the photo's axes, lets the person's grid near the face follow the face's
skin, and turns what follows the head about the neck. Done with NumPy that took about a fifth of a frame's time
(gathers and scatters over some 11 000 vertices, each a new array); here it is one pass over the vertices with
no array made per frame.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def pose(values, active, fields, rest, scale, rotation, offset, layer_rest, skin, skin_nearest, skin_weights,
         turning, follows, pivot, turned, turn, points):  # pragma: no cover - compiled
    """Write every drawn vertex in the photo's axes into ``points`` (n_rig + n_layer, 3).

    Parameters
    ----------
    values : float (68,)
        The frame's FAP values (the head's turn, FAP 48-50, excluded: it is ``turn``).
    active : int (k,)
        The FAPs (0-based) whose fields move the face in this frame.
    fields : float32 (68, n_rig, 3)
        Each FAP's displacement per unit, head axes (cm).
    rest : float (n_rig, 3)
        The head at rest, head axes (cm).
    scale, rotation, offset
        Head axes to the photo's: ``scale * (p @ rotation.T) + offset``.
    layer_rest : float (n_layer, 3)
        The person's grid at rest, photo axes.
    skin, skin_nearest, skin_weights : int (s,), int (s, 4), float (s, 4)
        The grid vertices that follow the face, the face vertices each follows and their weights.
    turning, follows : int (m,), float (n,)
        The vertices that follow the head's turn, and how much each does.
    pivot : float (3,)
        The neck's pivot, photo axes.
    turned, turn : bool, float (3, 3)
        Whether the head turns, and the turn's rotation.
    points : float (n_rig + n_layer, 3)
        Written: the vertices.

    Returns
    -------
    None
    """
    n_rig = rest.shape[0]
    moved = np.zeros((n_rig, 3))
    for i in range(n_rig):
        dx = dy = dz = 0.0
        for f in active:
            value = values[f]
            dx += value * fields[f, i, 0]
            dy += value * fields[f, i, 1]
            dz += value * fields[f, i, 2]
        moved[i, 0], moved[i, 1], moved[i, 2] = dx, dy, dz
        x, y, z = rest[i, 0] + dx, rest[i, 1] + dy, rest[i, 2] + dz
        for k in range(3):
            points[i, k] = scale * (x * rotation[k, 0] + y * rotation[k, 1] + z * rotation[k, 2]) + offset[k]
    points[n_rig:] = layer_rest
    for s in range(skin.shape[0]):
        sx = sy = sz = 0.0
        for j in range(skin_nearest.shape[1]):
            v, w = skin_nearest[s, j], skin_weights[s, j]
            sx += moved[v, 0] * w
            sy += moved[v, 1] * w
            sz += moved[v, 2] * w
        i = n_rig + skin[s]
        for k in range(3):
            points[i, k] += scale * (sx * rotation[k, 0] + sy * rotation[k, 1] + sz * rotation[k, 2])
    if turned:
        for i in turning:
            x, y, z = points[i, 0] - pivot[0], points[i, 1] - pivot[1], points[i, 2] - pivot[2]
            share = follows[i]
            for k in range(3):
                turned = x * turn[k, 0] + y * turn[k, 1] + z * turn[k, 2] + pivot[k]
                points[i, k] += share * (turned - points[i, k])


@njit(cache=True, nogil=True)
def vertex_normals(points, triangles, out):  # pragma: no cover - compiled
    """Unit normals (the sum of the triangles' area-weighted normals round each vertex) of the vertices
    ``triangles`` use, into ``out``'s first rows; a vertex no triangle uses keeps a zero normal.

    Parameters
    ----------
    points : float (n, 3)
        The vertices.
    triangles : int (m, 3)
        The triangles whose normals count.
    out : float (k, 3)
        Written: the normals of vertices 0 to k - 1.

    Returns
    -------
    None
    """
    n = out.shape[0]
    sums = np.zeros((n, 3))
    for t in range(triangles.shape[0]):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        ux, uy, uz = points[b, 0] - points[a, 0], points[b, 1] - points[a, 1], points[b, 2] - points[a, 2]
        vx, vy, vz = points[c, 0] - points[a, 0], points[c, 1] - points[a, 1], points[c, 2] - points[a, 2]
        nx, ny, nz = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        for corner in (a, b, c):
            sums[corner, 0] += nx
            sums[corner, 1] += ny
            sums[corner, 2] += nz
    for i in range(n):
        norm = max(np.sqrt(sums[i, 0] ** 2 + sums[i, 1] ** 2 + sums[i, 2] ** 2), 1e-12)
        out[i, 0], out[i, 1], out[i, 2] = sums[i, 0] / norm, sums[i, 1] / norm, sums[i, 2] / norm


@njit(cache=True, nogil=True)
def bounds(screen, chosen):  # pragma: no cover - compiled
    """The box round some points.

    Parameters
    ----------
    screen : float (n, 2 or more)
        Points (x, y first).
    chosen : int (k,)
        The rows that count.

    Returns
    -------
    tuple of float
        (x low, y low, x high, y high).
    """
    low_x = low_y = np.inf
    high_x = high_y = -np.inf
    for i in chosen:
        x, y = screen[i, 0], screen[i, 1]
        low_x, high_x = min(low_x, x), max(high_x, x)
        low_y, high_y = min(low_y, y), max(high_y, y)
    return low_x, low_y, high_x, high_y
