"""FAPs moving the head: each FAP a displacement field over the mesh, the head turning about the neck.

A FAP of value ``a`` moves its MPEG-4 feature point by ``a`` x its unit (the face unit / 1024, or 1e-5 rad) in
the standard's direction, and the skin round it by the same motion times a weight that falls off through the
FAP's region of influence. Every field is linear in the FAP's value (as in MPEG-4 players: a displacement per
unit, times the value), so a frame is ``rest + sum(value_f * field_f)``; the rotations of the jaw and the
eyeballs enter as their small-angle fields (tangent to the arc: the chin moves 1 MNS unit down per unit of
FAP 3, and a little back). The same fields are the morph targets of the glTF file and the browser's head, so
all three show one face. The head then turns rigidly about the top of the spine by FAP 48-50:
R = Rz(roll) Ry(yaw) Rx(pitch), + pitch bows, + yaw turns to the head's own left, + roll tilts to its right.

The regions, per group (all distances in cm on the neutral face; see ``docs/head.md``):

- jaw (3, 14, 15, 18): the lower lip, the chin and the jaw below the mouth line, the lower teeth and the tongue;
- lips (4-13, 16, 17 inner; 51-60 outer): along the lip, hat functions through the corner, the midpoints and the
  middle add up to one; across it, an inner-lip FAP weighs 1 on the inner lip line falling to 0 on the outer
  one, an outer-lip FAP the other way round and on into the skin for 1.6 cm;
- eyelids (19-22): each lid's edge moves in proportion to its opening at that point, so 1024 IRISD closes it;
- brows (31-38): hats along the brow for inner, middle and outer, 3 cm of forehead above and 1 cm below;
- cheeks (39-42), nose (61-64), eyeballs (23-28), tongue (43-46): a raised-cosine falloff round the point.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..fap.table import BY_NUMBER, HEAD_FAPS, N_FAPS, RADIANS_PER_AU
from .mesh import (
    BROW_LEFT,
    BROW_RIGHT,
    EYE_LEFT,
    EYE_RIGHT,
    FACE,
    JAW_PIVOT,
    LIDS_LEFT,
    LIDS_RIGHT,
    LOWER_TEETH,
    MOUTH_INSIDE,
    N_FACE_VERTICES,
    NECK_PIVOT,
    TONGUE,
    HeadMesh,
    build_head,
    lip_coordinates,
)

#: Direction of each positive motion word in head axes (x to the head's left, y up, z forwards).
_DIRECTIONS = {"up": (0, 1, 0), "down": (0, -1, 0), "left": (1, 0, 0), "right": (-1, 0, 0), "forward": (0, 0, 1)}


def _falloff(distance: np.ndarray, radius: float) -> np.ndarray:
    """Raised cosine: 1 at distance 0, 0 from ``radius`` on."""
    x = np.clip(np.asarray(distance) / radius, 0.0, 1.0)
    return 0.5 * (1.0 + np.cos(np.pi * x))


def _hats(x: np.ndarray, knots: list[float]) -> np.ndarray:
    """Piecewise-linear hat functions on sorted ``knots`` (k, n): they add up to 1, flat past the ends."""
    out = np.zeros((len(knots), len(x)))
    for k in range(len(knots)):
        values = np.zeros(len(knots))
        values[k] = 1.0
        out[k] = np.interp(x, knots, values)
    return out


@dataclass(frozen=True)
class HeadRig:
    """The head at rest and one displacement field per FAP.

    Attributes
    ----------
    mesh : HeadMesh
    fields : float32 (68, n, 3)
        Field ``f - 1`` is the displacement, in cm, of every vertex per unit of FAP ``f`` (zero where the FAP
        moves nothing: 1, 2, 48-50 and the FAPs this head has no part for).
    supported : tuple of int
        FAPs the head shows (48-50 included).
    """

    mesh: HeadMesh
    fields: np.ndarray
    supported: tuple[int, ...]

    def deform(self, values: np.ndarray) -> np.ndarray:
        """Vertices (n, 3) for one frame's 68 FAP values (0 = neutral; NaN counts as 0)."""
        values = np.nan_to_num(np.asarray(values, float).reshape(N_FAPS))
        active = np.flatnonzero((values != 0) & self.moving)
        vertices = self.mesh.vertices.astype(np.float64)
        if active.size:
            vertices = vertices + np.tensordot(values[active], self.fields[active], axes=1)
        pitch, yaw, roll = (values[f - 1] * RADIANS_PER_AU for f in HEAD_FAPS)
        if pitch or yaw or roll:
            pivot = np.asarray(NECK_PIVOT)
            share = self.turn_shares
            turning = share > 0
            turned = (vertices[turning] - pivot) @ rotation(pitch, yaw, roll).T + pivot
            vertices[turning] += share[turning, None] * (turned - vertices[turning])
        return vertices

    @functools.cached_property
    def turn_shares(self) -> np.ndarray:
        """float (n,): how much of the head's turn each vertex follows (see ``HeadMesh.follows``)."""
        return self.mesh.turn_share()

    @functools.cached_property
    def moving(self) -> np.ndarray:
        """bool (68,): the FAPs whose field moves a vertex."""
        return np.abs(self.fields).max(axis=(1, 2)) > 0

    def unsupported(self, faps: np.ndarray | list[int]) -> list[int]:
        """Of ``faps``, those this head does not show (the high-level 1 and 2 included)."""
        return [int(f) for f in faps if int(f) not in self.supported]


def rotation(pitch_rad: float, yaw_rad: float, roll_rad: float) -> np.ndarray:
    """R = Rz(roll) Ry(yaw) Rx(pitch) in head axes, with the FAP signs (see the module doc)."""
    cx, sx = math.cos(pitch_rad), math.sin(pitch_rad)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    cz, sz = math.cos(roll_rad), math.sin(roll_rad)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


@functools.lru_cache(maxsize=1)
def head_rig() -> HeadRig:
    """The rig of the canonical head (built once)."""
    return build_rig(build_head())


def build_rig(mesh: HeadMesh) -> HeadRig:
    """Every FAP's field on ``mesh`` (see the module doc for the regions)."""
    builder = _RigBuilder(mesh)
    for region in (builder.jaw, builder.lips, builder.eyelids, builder.brows, builder.cheeks_and_nose,
                   builder.eyeballs, builder.tongue):
        region()
    return HeadRig(mesh, builder.fields.astype(np.float32), tuple(sorted(builder.supported)))


class _RigBuilder:
    """The fields of one mesh, region by region; later regions read what earlier ones found (the jaw's
    weights, the lips' coordinates)."""

    def __init__(self, mesh: HeadMesh) -> None:
        self.mesh = mesh
        self.layout = mesh.layout.astype(np.float64)
        self.n = len(self.layout)
        self.face = mesh.part == FACE
        self.units = mesh.units
        self.fields = np.zeros((N_FAPS, self.n, 3))
        self.supported: set[int] = set(HEAD_FAPS)
        self.lip_coords = lip_coordinates(self.layout[:N_FACE_VERTICES])
        self.x, self.y = self.layout[:, 0], self.layout[:, 1]
        self.jaw_weights = np.zeros(self.n)
        self.face_jaw = np.zeros(N_FACE_VERTICES)

    def put(self, fap: int, weights: np.ndarray, direction: np.ndarray | None = None) -> None:
        """FAP ``fap`` moves each vertex by its weight along ``direction`` (default: the FAP's own)."""
        info = BY_NUMBER[fap]
        d = np.asarray(_DIRECTIONS[info.positive_motion], float) if direction is None else direction
        self.fields[fap - 1] = weights[:, None] * d[None, :] * self.units.unit_cm(info.fapu)
        self.supported.add(fap)

    def jaw(self) -> None:
        layout, n, units, fields = self.layout, self.n, self.units, self.fields
        x, y, mesh, put = self.x, self.y, self.mesh, self.put
        lips = self.lip_coords
        # the jaw: below the mouth line, sharp at the lips and widening on the cheeks; lower teeth and tongue whole
        jaw = np.zeros(n)
        face_x, face_y = x[:N_FACE_VERTICES], y[:N_FACE_VERTICES]
        below = lips.mouth_y(face_x) - face_y
        band = 0.15 + 0.45 * np.maximum(np.abs(face_x) - lips.corner_x, 0.0)
        face_jaw = np.clip(0.5 + below / (2 * band), 0, 1)
        face_jaw = face_jaw * face_jaw * (3 - 2 * face_jaw)
        face_jaw = np.where(lips.in_lips, (~lips.upper).astype(float), face_jaw)
        face_jaw *= 1.0 - _falloff(np.maximum(7.2 - np.abs(face_x), 0.0), 2.0) * (face_y > -7.0)  # the hinge
        jaw[:N_FACE_VERTICES] = face_jaw
        jaw[(mesh.part == LOWER_TEETH) | (mesh.part == TONGUE)] = 1.0
        inside = mesh.part == MOUTH_INSIDE
        jaw[inside] = np.clip(0.5 - (y[inside] - lips.mouth_y(x[inside])) / 1.2, 0, 1)
        pivot = np.asarray(JAW_PIVOT)
        arm = layout - pivot
        swing = np.column_stack([np.zeros(n), -arm[:, 2], arm[:, 1]])  # d/dangle of a turn about +x (chin down)
        chin = mesh.feature_points["2.1"]
        per_unit = units.unit_cm("MNS") / abs(swing[chin, 1])  # the chin moves 1 MNS unit down per unit
        fields[3 - 1] = (jaw * per_unit)[:, None] * swing
        self.supported.add(3)
        put(14, jaw)
        put(15, jaw)
        chin_boss = layout[mesh.feature_points["2.10"]]
        put(18, jaw * _falloff(np.linalg.norm(layout - chin_boss, axis=1), 2.2) * (y < lips.mouth_y(x) - 0.6))
        self.jaw_weights, self.face_jaw = jaw, face_jaw

    def lips(self) -> None:
        layout, n, face, x, mesh, put = self.layout, self.n, self.face, self.x, self.mesh, self.put
        lips, face_jaw = self.lip_coords, self.face_jaw
        # the lips
        inner = np.zeros(n)
        inner[:N_FACE_VERTICES] = lips.inner
        in_lips = np.zeros(n, bool)
        in_lips[:N_FACE_VERTICES] = lips.in_lips
        skin = np.zeros(n)
        skin[:N_FACE_VERTICES] = np.where(lips.in_lips, 1.0 - lips.inner, _falloff(lips.outside_cm, 1.6))
        upper = np.zeros(n)
        upper[:N_FACE_VERTICES] = np.where(lips.in_lips, lips.upper, 1.0 - face_jaw)
        lower = np.zeros(n)
        lower[:N_FACE_VERTICES] = np.where(lips.in_lips, ~lips.upper, face_jaw)
        on_face = face.astype(float)
        # the mouth's dark inside follows the inner lips' corners (stretched or raised), so a wide mouth never
        # opens onto what is behind the head at its corners
        cavity = (mesh.part == MOUTH_INSIDE).astype(float)

        def point(name: str) -> np.ndarray:
            return layout[mesh.feature_points[name]]

        def hats_through(names: tuple[str, str, str, str, str]) -> tuple[np.ndarray, float]:
            """Hats through (right corner, right midpoint, middle, left midpoint, left corner), faded past the
            corners; and the corners' distance from the middle."""
            knots = [float(point(name)[0]) for name in names]
            corner_x = (knots[-1] - knots[0]) / 2
            along = _hats(x, knots)
            past = _falloff(np.maximum(np.abs(x) - corner_x, 0.0), 1.6)  # past the corners the corner's hat fades
            along[0] *= np.where(x < -corner_x, past, 1.0)
            along[-1] *= np.where(x > corner_x, past, 1.0)
            return along, corner_x

        # vertical: (upper middle, upper midpoints, lower middle, lower midpoints, corners) inner, then outer
        rings = ((inner, (4, 8, 9, 5, 10, 11, 12, 13), ("2.5", "2.7", "2.2", "2.6", "2.4"),
                  ("2.5", "2.9", "2.3", "2.8", "2.4"), (6, 7)),
                 (skin, (51, 55, 56, 52, 57, 58, 59, 60), ("8.4", "8.6", "8.1", "8.5", "8.3"),
                  ("8.4", "8.8", "8.2", "8.7", "8.3"), (53, 54)))
        for depth, faps, upper_points, lower_points, (stretch_l, stretch_r) in rings:
            t_mid, t_l, t_r, b_mid, b_l, b_r, c_l, c_r = faps
            top, corner_x = hats_through(upper_points)
            bottom, _ = hats_through(lower_points)
            put(t_mid, depth * upper * top[2])
            put(t_l, depth * upper * top[3])
            put(t_r, depth * upper * top[1])
            put(b_mid, depth * lower * bottom[2])
            put(b_l, depth * lower * bottom[3])
            put(b_r, depth * lower * bottom[1])
            inside = cavity if depth is inner else 0.0  # the inner corners carry the mouth's inside
            put(c_l, depth * on_face * np.maximum(upper * top[4], lower * bottom[4])
                + inside * np.maximum(top[4], bottom[4]))
            put(c_r, depth * on_face * np.maximum(upper * top[0], lower * bottom[0])
                + inside * np.maximum(top[0], bottom[0]))
            # horizontal: the corners stretch the lip evenly from the middle
            past = _falloff(np.maximum(np.abs(x) - corner_x, 0.0), 1.6)
            spread = np.clip(np.abs(x) / corner_x, 0, 1) * np.where(np.abs(x) > corner_x, past, 1.0)
            put(stretch_l, (depth * on_face + inside) * spread * (x > 0))
            put(stretch_r, (depth * on_face + inside) * spread * (x < 0))
        put(16, lower * on_face * _falloff(np.linalg.norm(layout - point("2.3"), axis=1), 2.2))
        put(17, upper * on_face * _falloff(np.linalg.norm(layout - point("2.2"), axis=1), 2.2))

    def eyelids(self) -> None:
        layout, face, units, x, y, put = self.layout, self.face, self.units, self.x, self.y, self.put
        # the eyelids: the edge in proportion to its opening, the lid above (or below) it following
        for fap_top, fap_bottom, (upper_ring, lower_ring) in ((19, 21, LIDS_LEFT), (20, 22, LIDS_RIGHT)):
            top, bottom = layout[list(upper_ring)], layout[list(lower_ring)]
            order = np.argsort(top[:, 0])
            top_x, top_y = top[order, 0], top[order, 1]
            order = np.argsort(bottom[:, 0])
            bottom_x, bottom_y = bottom[order, 0], bottom[order, 1]
            reach = (x >= min(top_x[0], bottom_x[0]) - 0.25) & (x <= max(top_x[-1], bottom_x[-1]) + 0.25) & face
            opening = np.clip(np.interp(x, top_x, top_y) - np.interp(x, bottom_x, bottom_y), 0, None)
            opening /= max(units.irisd0, 1e-9)
            above = y - np.interp(x, top_x, top_y)
            below = np.interp(x, bottom_x, bottom_y) - y
            lid_top = reach * opening * np.where(above >= -1e-6, _falloff(np.maximum(above, 0), 0.9), 0.0)
            lid_bottom = reach * opening * np.where(below >= -1e-6, _falloff(np.maximum(below, 0), 0.6), 0.0)
            lid_top[list(upper_ring)] = opening[list(upper_ring)]
            lid_bottom[list(lower_ring)] = opening[list(lower_ring)]
            for ring in (upper_ring, lower_ring):  # the corners are shared by both lids and stay
                lid_top[[ring[0], ring[-1]]] = lid_bottom[[ring[0], ring[-1]]] = 0.0
            put(fap_top, lid_top)
            put(fap_bottom, lid_bottom)

    def brows(self) -> None:
        layout, face, x, y, mesh, put = self.layout, self.face, self.x, self.y, self.mesh, self.put
        # the brows: inner, middle and outer hats along the brow; the forehead above and the lid below follow
        for sign, (brow_upper, brow_lower), (inner_fap, middle_fap, outer_fap), squeeze in (
                (1.0, BROW_LEFT, (31, 33, 35), 37), (-1.0, BROW_RIGHT, (32, 34, 36), 38)):
            edge_up, edge_down = layout[list(brow_upper)], layout[list(brow_lower)]
            side = sign * x
            names = ("4.1", "4.3", "4.5") if sign > 0 else ("4.2", "4.4", "4.6")
            positions = [abs(float(layout[mesh.feature_points[name], 0])) for name in names]
            hats = _hats(side, positions)  # inner, middle, outer; flat past both ends
            hats[0] *= np.clip(0.5 + side / (2 * positions[0]), 0, 1)  # across the middle: half each side
            order_up, order_down = np.argsort(sign * edge_up[:, 0]), np.argsort(sign * edge_down[:, 0])
            up_y = np.interp(side, sign * edge_up[order_up, 0], edge_up[order_up, 1])
            down_y = np.interp(side, sign * edge_down[order_down, 0], edge_down[order_down, 1])
            lid_line = np.interp(side, sorted(sign * layout[list((LIDS_LEFT if sign > 0 else LIDS_RIGHT)[0]), 0]),
                                 layout[list((LIDS_LEFT if sign > 0 else LIDS_RIGHT)[0]), 1][
                                     np.argsort(sign * layout[list((LIDS_LEFT if sign > 0 else LIDS_RIGHT)[0]), 0])])
            # below the brow, the skin down to the lid's fold stretches evenly (no band of stretched skin under
            # the brow, which on a photo head reads as a light smear)
            below = np.maximum(down_y - lid_line - 0.05, 0.3)
            vertical = np.where(y >= down_y, _falloff(np.maximum(y - up_y, 0), 3.0),
                                _falloff(down_y - y, below) * (y > lid_line + 0.05))
            lateral = _falloff(np.maximum(side - positions[-1], 0), 1.5)
            region = vertical * lateral * face * (side > -positions[0])
            for fap, hat in zip((inner_fap, middle_fap, outer_fap), hats, strict=True):
                put(fap, region * hat)
            put(squeeze, region)

    def cheeks_and_nose(self) -> None:
        layout, face, mesh, put = self.layout, self.face, self.mesh, self.put
        jaw = self.jaw_weights
        # cheeks, nose
        for fap, where, radius in ((39, "5.1", 2.2), (40, "5.2", 2.2), (41, "5.3", 2.2), (42, "5.4", 2.2),
                                   (61, "9.1", 0.9), (62, "9.2", 0.9), (63, "9.3", 1.4), (64, "9.3", 1.4)):
            distance = np.linalg.norm(layout - layout[mesh.feature_points[where]], axis=1)
            weights = _falloff(distance, radius) * face
            if fap in (41, 42):
                weights *= 1.0 - jaw
            put(fap, weights)

    def eyeballs(self) -> None:
        layout, n, fields, mesh, put = self.layout, self.n, self.fields, self.mesh, self.put
        # the eyeballs: small-angle turns about their centres, and thrust
        for (yaw, pitch, thrust), part, centre in (((23, 25, 27), EYE_LEFT, mesh.eye_centres[0]),
                                                  ((24, 26, 28), EYE_RIGHT, mesh.eye_centres[1])):
            on = mesh.part == part
            arm = (layout - centre) * on[:, None]
            fields[yaw - 1] = np.column_stack([arm[:, 2], np.zeros(n), -arm[:, 0]]) * RADIANS_PER_AU  # about +y
            fields[pitch - 1] = np.column_stack([np.zeros(n), -arm[:, 2], arm[:, 1]]) * RADIANS_PER_AU  # about +x
            self.supported.update((yaw, pitch))
            put(thrust, on.astype(float))

    def tongue(self) -> None:
        layout, n, mesh, put = self.layout, self.n, self.mesh, self.put
        # the tongue: its tip is the front half
        tongue = mesh.part == TONGUE
        if tongue.any():
            front = layout[tongue, 2]
            tip = np.zeros(n)
            tip[tongue] = np.clip((front - front.min()) / max(np.ptp(front), 1e-9) * 2 - 1, 0, 1)
            put(43, tip)
            put(44, tip)
            put(45, tip)
            put(46, tongue.astype(float))
