"""One photo of a person becomes the head: MPEG-4's facial definition parameters measured on that face.

MPEG-4 calibrates its generic face to a person with facial definition parameters (FDP: the feature points
and a texture). Here the photo gives both:

1. **The face.** MediaPipe's face landmarker (:mod:`.landmarks`) finds the face's 478 landmarks in the photo.
   The canonical face is fitted to them by a similarity (Umeyama's least squares: scale, rotation,
   translation), which gives the photo's head pose; the landmarks taken back through it are the person's
   face in the head's axes, in place of the canonical one (the depth half the landmarker's, half the
   canonical face's, which is steadier). :func:`~.mesh.build_head` builds the head on it, so the feature points
   and the face units (IRISD0, ES0, ENS0, MNS0, MW0) are this person's and every FAP moves the face by its
   own proportions.
2. **The texture.** Each vertex of the face and of the eyeballs takes the colour of the photo where it is
   seen at rest: a still stream shows the photo as it was. Each eyeball has a picture of its own, the photo in
   the lids' opening and the iris's and the white's colours where the lids hide it (:mod:`.eyes`), so a
   raised lid or a turned eye uncovers the eye, not the lid's skin. The lips are closed at rest (MPEG-4's neutral
   face); where they are apart in the photo, the lips' texture stretches over the gap. The teeth, the tongue
   and the mouth's dark inside are the head's own, shaded, sized to this mouth.
3. **The rest of the person.** The person is told from the background by MediaPipe's selfie segmentation
   model, its edge placed on the photo's colours by OpenCV's GrabCut (:func:`.person.person_mask`). A grid over the
   person carries the photo's hair, ears, neck and shoulders on a plausible depth (the face's own near its
   edge, a skull's front further out, a plane behind the neck lower down); it turns with the head above
   the chin and stays still at the shoulders, the neck bending between.
4. **The background** stays as photographed; behind the person it is filled with the background round it,
   blurred (a normalised convolution), so that what a turned head uncovers is background, not a hole, a
   streak or the head twice. Along the outline the matte (:func:`.person.person_matte`) tells how much of
   each pixel is the person's (:attr:`PhotoHead.coverage`) and what colour the person is there, so a turned
   head moves no strip of the background with it and leaves none of its hair's edge behind.

The photo is seen by an orthographic camera (a face's depth is small beside its distance from the camera),
so the frames keep the photo's framing and pixels. Everything needs the ``track`` extra (MediaPipe, whose
wheel brings OpenCV): ``pip install 'visual-prosody[track]'``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import PhotoError
from ..fap.table import HEAD_FAPS, N_FAPS, RADIANS_PER_AU
from . import posing
from .eyes import eye_pictures, lashes_to_lids
from .landmarks import found_faces
from .mesh import (
    EYE_LEFT,
    EYE_RIGHT,
    FACE,
    LIDS_LEFT,
    LIDS_RIGHT,
    LIP_OUTER_LOWER,
    LIP_OUTER_UPPER,
    LOWER_TEETH,
    MOUTH_INSIDE,
    N_FACE_VERTICES,
    NECK_PIVOT,
    TONGUE,
    UPPER_TEETH,
    canonical_face,
    face_outline,
    smoothstep,
)
from .person import fill_background, inside_polygon, person_mask, person_matte
from .raster import Canvas, rasterise_textured
from .render import SUPERSAMPLE
from .rig import HeadRig, build_rig, rotation

#: Photos larger than this are refused before they are decoded (bounded memory).
MAX_PHOTO_PIXELS = 60_000_000
#: Larger photos are scaled down to about this many pixels before use (the frames' default size).
WORK_PIXELS = 1920 * 1080
#: A face narrower than this (in the photo's pixels, after scaling) is too small to animate.
MIN_FACE_PIXELS = 80
#: A face turned further than this from the camera (yaw or pitch) is refused.
MAX_TURN_DEG = 30.0
#: Lips apart by more than this fraction of the mouth's width: said in a note (a closed mouth animates best).
LIPS_APART = 0.08
#: Eyes open less than this fraction of their width (the lids' gap over the corners' distance, both eyes' mean;
#: open eyes measure about 0.3, a blink under 0.1): said in a note.
EYES_CLOSED = 0.12
#: Brows raised further than this in the photo (the mean of the landmarker's browInnerUp, browOuterUpLeft and
#: browOuterUpRight blendshapes): said in a note. In 4,080 frames of seven people speaking (the StyleTalk clips)
#: this mean reaches at most 0.59. FAP raises add to the photo's, and the landmarker stops following brows raised
#: further (it reads them lower again), so motion tracked back from such a head understates the brows.
BROWS_RAISED = 0.65
#: The blendshapes whose mean says how far the photo's brows are raised.
BROW_RAISE_SHAPES = ("browInnerUp", "browOuterUpLeft", "browOuterUpRight")
#: The share of the landmarker's depth kept in the fitted face (the rest is the canonical face's).
DEPTH_TRUST = 0.0
#: The person's grid follows the face's skin within the face and fades out this far outside it (cm): the skin
#: under the chin goes down with the jaw over about 3 cm of the neck, not the collar. A steeper fade (1.5 cm)
#: bent the grid's cells under an opening jaw, and the photo's chin line showed as a saw-tooth.
SKIN_FOLLOW_CM = 3.0
#: The motion is seen as by a camera this far from the face (a video call's distance), laid over the photo's
#: framing: the tracker reads turns rendered without perspective at 0.55-0.7 of their size, with it 0.7-1.2.
CAMERA_DISTANCE_CM = 60.0
#: How far the person's grid goes on past an edge of the photo that cuts the person, cm (a nod of 9 degrees moves
#: the top of the head about 3 cm, a turn of 15 degrees its side about 4).
CUT_REACH_CM = 6.0
#: The percentile of the face's brightness that tells the photo's light (:func:`photo_exposure`).
EXPOSURE_PERCENTILE = 90
#: The mouth's inside is drawn as if this much further back, so the skin round the lips always hides it.
MOUTH_DEPTH_BIAS_CM = 3.0
#: The mouth's inside is drawn, the face photographed: where the inside shows, the frame is blurred by this much
#: (a Gaussian's sigma, in the photo's pixels), so that its edges are about as soft as a photo's own (a video
#: frame's edges spread over 2-3 pixels; the drawn ones over one at most). Looked at on four people, 0.9
#: blends the inside into the lips; 1.5 smears the teeth.
INSIDE_SOFTNESS_PX = 0.9
#: The light that stays put while the head turns (towards the light, camera axes) and its ambient share.
RELIGHT_DIRECTION = np.array([0.0, 0.35, 1.0]) / np.linalg.norm([0.0, 0.35, 1.0])
RELIGHT_AMBIENT = 0.35  # > 0: the ratio below is bounded
#: A turned surface's light over its light in the photo is kept within these bounds.
RELIGHT_RANGE = (0.6, 1.4)
#: The shading of a turned face fades out over this distance towards the face's edge (cm).
RELIGHT_FADE_CM = 2.0
#: Side of the person layer's grid cells, as a fraction of the photo's longer side.
GRID_STEP = 1 / 110
#: The person's grid is left out this far inside the face's outline (the face always covers it there), cm.
HIDDEN_UNDER_FACE_CM = 1.0
#: Samples per pixel along each axis. One: a pixel inside a triangle reads the photo at its centre, as four
#: samples averaged do (their barycentric weights are averaged first); only pixels that straddle an edge differ,
#: and the photo head's edges are the photo's own, continuous across its triangles, or softened (the mouth's
#: inside, the outline's coverage). Four samples took 1.7-1.9 times as long for 0.1 of a grey level on average
#: (on six people's heads speaking: 0.02-0.08 % of the pixels differed by more than 16 levels, along the edges).
PHOTO_SUPERSAMPLE = 1
#: Samples per pixel along each axis round the mouth's inside, which is drawn (teeth a pixel or two high).
INSIDE_SUPERSAMPLE = 2

# Head axes (cm): the skull whose front carries the hair round the face, and the plane behind the neck.
_SKULL_CENTRE, _SKULL_RADII = np.array([0.0, 2.5, -3.0]), np.array([8.2, 11.0, 9.4])
_NECK_PLANE_Z = -4.0
#: The person layer's depth falls off no steeper than this (cm per cm across the picture): it does not fold over
#: itself under turns up to atan(1 / slope), 27 degrees.
MAX_DEPTH_SLOPE = 2.0
#: How far apart (cm) two of the outline's points may be from a point of the grid and still both give it their
#: depth (Gaussian weights on the difference of their distances).
EDGE_DEPTH_SPREAD_CM = 0.7
#: Parts of the head drawn on a photo: the textured face and eyes, the mouth's inside shaded.
_TEXTURED_PARTS = (FACE, EYE_LEFT, EYE_RIGHT)
_SHADED_PARTS = (UPPER_TEETH, LOWER_TEETH, TONGUE, MOUTH_INSIDE)


@dataclass(frozen=True)
class PhotoHead:
    """A person's head made from one photo (see the module doc); :class:`PhotoRenderer` draws its frames.

    Attributes
    ----------
    name : the photo's file name.
    image : uint8 (height, width, 3), the photo as used (scaled down if it was larger than
        :data:`WORK_PIXELS`; even sides).
    rig : the head fitted to the face, with its FAP fields.
    scale : photo pixels per cm of the head.
    rotation : (3, 3), head axes to photo axes (x right, y up, z towards the camera; pixels).
    offset : (3,), where the head's origin is in photo axes.
    uv : float (n, 2), each rig vertex's place in :attr:`texture` (pixels, y down): the photo where it is seen at
        rest; the eyeballs' in their own pictures below the photo.
    layer_vertices : float (k, 3), the person layer's grid at rest, in head axes.
    layer_uv : float (k, 2), its place in the photo.
    layer_weight : float (k,), how much of the head's turn each grid vertex follows (1 above the chin,
        0 at the shoulders).
    layer_triangles : int (q, 3).
    background : uint8 (height, width, 3), the photo with the person filled in (along the outline, the
        background's own colour where a pixel is part person).
    person : bool (height, width), where the person is.
    coverage : float32 (height, width), how much of each pixel is the person's (the matte,
        :func:`.person.person_matte`): 1 over the person, 0 off them, between along the outline; where it is
        below 1 the background shows through, so the grid's cells round the outline carry no background
        with them.
    notes : things worth telling the user (several faces, lips apart, eyes closed, brows raised,
        scaled down).
    eye_texture : uint8 (height + rows, width, 3), what the head's triangles show: the photo (along the
        person's outline, the person's colours without the background's) and, below it, each eyeball as it
        would look with the lids open (:func:`eye_pictures`); None: the photo alone (:attr:`texture` is
        either).
    """

    name: str
    image: np.ndarray
    rig: HeadRig
    scale: float
    rotation: np.ndarray
    offset: np.ndarray
    uv: np.ndarray
    layer_vertices: np.ndarray
    layer_uv: np.ndarray
    layer_weight: np.ndarray
    layer_triangles: np.ndarray
    background: np.ndarray
    person: np.ndarray
    coverage: np.ndarray
    notes: tuple[str, ...] = ()
    eye_texture: np.ndarray | None = None

    @property
    def texture(self) -> np.ndarray:
        """uint8 (rows, columns, 3): the image :attr:`uv` places the head's vertices in."""
        return self.image if self.eye_texture is None else self.eye_texture

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    @property
    def height(self) -> int:
        return int(self.image.shape[0])

    @property
    def texture_size(self) -> tuple[int, int]:
        """The texture's (width, height) in pixels: what :attr:`uv` is normalised by in a texture of 0..1."""
        return int(self.texture.shape[1]), int(self.texture.shape[0])

    def texture_with_coverage(self) -> np.ndarray:
        """uint8 (texture height, width, 4): :attr:`texture` with :attr:`coverage` as its alpha over the photo
        (opaque below it, where the eyeballs' pictures are)."""
        alpha = np.full(self.texture.shape[:2], 255, np.uint8)
        alpha[:self.height, :self.width] = np.round(255 * np.clip(self.coverage, 0, 1)).astype(np.uint8)
        return np.dstack([self.texture, alpha])

    def to_photo(self, vertices: np.ndarray) -> np.ndarray:
        """Head-axes points (n, 3), cm -> photo axes (x right, y up, z towards the camera), pixels."""
        return self.scale * (np.asarray(vertices, float) @ self.rotation.T) + self.offset

    def from_photo(self, points: np.ndarray) -> np.ndarray:
        """Photo-axes points (n, 3) -> head axes (cm)."""
        return ((np.asarray(points, float) - self.offset) @ self.rotation) / self.scale

    @property
    def pose_deg(self) -> tuple[float, float, float]:
        """The photo's head pose (pitch, yaw, roll) in degrees, with the FAP signs."""
        return tuple(math.degrees(a) for a in _angles(self.rotation))  # type: ignore[return-value]


# ---------------------------------------------------------------------------------------------------------
# reading the photo


def read_photo(path: str | os.PathLike[str]) -> tuple[np.ndarray, list[str]]:
    """The photo at ``path`` as RGB uint8 (EXIF orientation applied, scaled down to about
    :data:`WORK_PIXELS`, cropped to even sides), and notes.

    Raises
    ------
    PhotoError
        Not a readable image, or larger than :data:`MAX_PHOTO_PIXELS`.
    """
    from PIL import Image, ImageOps, UnidentifiedImageError

    source = Path(path)
    if not source.is_file():
        raise PhotoError(f"{source}: no such photo" if not source.exists() else f"{source}: not a file")
    notes = []
    try:
        with Image.open(source) as opened:
            width, height = opened.size
            if width * height > MAX_PHOTO_PIXELS:
                raise PhotoError(f"{source}: {width} x {height} pixels is too large a photo (at most "
                                 f"{MAX_PHOTO_PIXELS / 1e6:.0f} megapixels)")
            if opened.format not in ("JPEG", "PNG", "MPO", "WEBP"):
                raise PhotoError(f"{source}: a {opened.format} image; give a JPEG or PNG photo")
            opened.draft("RGB", (width, height))
            image = ImageOps.exif_transpose(opened).convert("RGB")
    except (UnidentifiedImageError, Image.DecompressionBombError, OSError, SyntaxError, ValueError) as error:
        if isinstance(error, PhotoError):
            raise
        raise PhotoError(f"{source}: not an image that can be read as a photo (JPEG or PNG): "
                         f"{str(error).splitlines()[0] if str(error) else type(error).__name__}") from None
    if image.width * image.height > WORK_PIXELS:
        factor = math.sqrt(WORK_PIXELS / (image.width * image.height))
        size = (max(2, int(image.width * factor)), max(2, int(image.height * factor)))
        notes.append(f"the photo is scaled down from {image.width} x {image.height} to {size[0]} x {size[1]}")
        image = image.resize(size, Image.Resampling.LANCZOS)
    pixels = np.asarray(image)
    even = pixels[: pixels.shape[0] // 2 * 2, : pixels.shape[1] // 2 * 2]
    if even.shape[0] < 16 or even.shape[1] < 16:
        raise PhotoError(f"{source}: {image.width} x {image.height} pixels is too small a photo")
    return np.ascontiguousarray(even), notes


# ---------------------------------------------------------------------------------------------------------
# fitting the face


def similarity(source: np.ndarray, target: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``(s, R, t)`` minimising ``|target - (s R source + t)|^2`` over points (n, 3) (Umeyama, 1991).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> points = rng.normal(size=(20, 3))
    >>> turn = rotation(0.1, -0.3, 0.2)
    >>> s, r, t = similarity(points, 2.5 * points @ turn.T + [1.0, 2.0, 3.0])
    >>> round(s, 6), bool(np.allclose(r, turn)), np.round(t, 6).tolist()
    (2.5, True, [1.0, 2.0, 3.0])
    """
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    a, b = source - mu_s, target - mu_t
    covariance = b.T @ a / len(source)
    u, d, vt = np.linalg.svd(covariance)
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2, 2] = -1.0
    turn = u @ sign @ vt
    scale = float(np.trace(np.diag(d) @ sign) / (a * a).sum(axis=1).mean())
    return scale, turn, mu_t - scale * turn @ mu_s


def _angles(turn: np.ndarray) -> tuple[float, float, float]:
    """(pitch, yaw, roll) in rad of R = Rz(roll) Ry(yaw) Rx(pitch)."""
    yaw = math.asin(max(-1.0, min(1.0, -float(turn[2, 0]))))
    return math.atan2(turn[2, 1], turn[2, 2]), yaw, math.atan2(turn[1, 0], turn[0, 0])


def fit_face(landmarks: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """The person's face in head axes (468, 3), and the similarity (scale, rotation, offset) that puts the
    head into the photo's axes, from the landmarks (468+, 3) in pixels (x right, y down, z away)."""
    canonical, _ = canonical_face()
    points = np.asarray(landmarks, float)[:N_FACE_VERTICES] * np.array([1.0, -1.0, -1.0])
    scale, turn, offset = similarity(canonical, points)
    face = ((points - offset) @ turn) / scale
    face[:, 2] = DEPTH_TRUST * face[:, 2] + (1 - DEPTH_TRUST) * canonical[:, 2]
    return face, scale, turn, offset


def eye_opening(landmarks: np.ndarray) -> float:
    """How open a face's eyes are in its landmarks (478, 2+): the gap between the lids over the distance between
    the eye's corners, the two eyes' mean (open eyes about 0.3, closed under 0.1)."""
    def one(upper: int, lower: int, outer: int, inner: int) -> float:
        width = float(np.linalg.norm(landmarks[outer, :2] - landmarks[inner, :2]))
        return float(np.linalg.norm(landmarks[upper, :2] - landmarks[lower, :2])) / max(width, 1e-9)

    return (one(159, 145, 33, 133) + one(386, 374, 263, 362)) / 2


def photo_head(photo: str | os.PathLike[str] | np.ndarray, *, name: str | None = None) -> PhotoHead:
    """The head of the person in ``photo`` (a JPEG or PNG path, or an RGB uint8 array).

    Raises
    ------
    PhotoError
        No face, a face too small or turned too far, an unreadable or too large image, or the track extra
        missing; several faces, lips apart, eyes closed and brows raised are said in
        :attr:`PhotoHead.notes`.
    """
    from ..errors import TrackingError

    if isinstance(photo, np.ndarray):
        image = np.ascontiguousarray(np.asarray(photo, np.uint8)[: photo.shape[0] // 2 * 2,
                                                                 : photo.shape[1] // 2 * 2, :3])
        notes: list[str] = []
        label = name or "photo"
    else:
        image, notes = read_photo(photo)
        label = name or Path(photo).name
    try:
        faces = found_faces(image)
    except TrackingError as error:
        raise PhotoError(f"{label}: {error}") from None
    if not faces:
        raise PhotoError(f"{label}: no face found in the photo (one person, roughly frontal, well lit)")
    landmarks = faces[0].points
    if len(faces) > 1:
        x, y = landmarks[:, :2].mean(axis=0)
        notes.append(f"{len(faces)} faces in the photo: the largest is used (centred at x {x:.0f}, y {y:.0f})")
    face_w = float(np.ptp(landmarks[:N_FACE_VERTICES, 0]))
    if face_w < MIN_FACE_PIXELS:
        raise PhotoError(f"{label}: the face is {face_w:.0f} pixels wide, too small to animate (at least "
                         f"{MIN_FACE_PIXELS}): a closer or larger photo")
    fitted = lashes_to_lids(landmarks)
    face, scale, turn, offset = fit_face(fitted)
    pitch, yaw, _ = (math.degrees(a) for a in _angles(turn))
    if abs(yaw) > MAX_TURN_DEG or abs(pitch) > MAX_TURN_DEG:
        raise PhotoError(f"{label}: the face is turned {abs(yaw):.0f} degrees sideways and {abs(pitch):.0f} up "
                         f"or down; at most {MAX_TURN_DEG:.0f}: a roughly frontal photo")
    gap = float(np.linalg.norm(landmarks[13, :2] - landmarks[14, :2]))
    width_lips = float(np.linalg.norm(landmarks[61, :2] - landmarks[291, :2]))
    if gap > LIPS_APART * width_lips:
        notes.append("the lips are apart in the photo: they close at rest, and a closed-mouth photo animates best")
    if eye_opening(landmarks) < EYES_CLOSED:
        notes.append("the eyes are closed or nearly so in the photo: they cannot open wider than it shows them, and "
                     "a photo with open eyes animates best")
    if np.mean([faces[0].shapes.get(name, 0.0) for name in BROW_RAISE_SHAPES]) > BROWS_RAISED:
        notes.append("the brows are raised in the photo: raises add to it, and a photo with the brows at rest "
                     "animates best")

    from .mesh import build_head

    rig = build_rig(build_head(face))
    mesh = rig.mesh

    def project(vertices: np.ndarray) -> np.ndarray:
        photo_points = scale * (vertices @ turn.T) + offset
        return np.column_stack([photo_points[:, 0], -photo_points[:, 1]])

    uv = project(mesh.vertices.astype(float))
    uv[:N_FACE_VERTICES] = project(mesh.layout[:N_FACE_VERTICES].astype(float))  # the lips as photographed
    person = person_mask(image, landmarks)
    alpha, foreground, background = _matted(image, person)
    # the person's colours along their outline (no background's in them), the eyeballs' pictures below
    texture, uv = eye_pictures(foreground, fitted, uv, mesh.part)
    layer = _person_layer(image.shape[:2], person, face, scale, turn, offset, landmarks)
    return PhotoHead(label, image, rig, scale, turn, offset, uv, *layer, background, person, alpha,
                     tuple(notes), texture)


def _matted(image: np.ndarray, person: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The person's matte, their colours and the background behind them (:func:`.person.person_matte`), such
    that at rest the frame is the photo.

    Behind the person the background is filled in. Where a pixel is mostly background it is the matte's estimate
    of the background's colour there, blending into the fill as the person's share grows to a half: beyond, that
    estimate is the person's colour as much as the background's, and a turned head showed it as a streak where
    the hair's edge had been. The person's colours then make up the rest: share x person + (1 - share) x
    background is the photo (the correction is at most twice the estimate's difference from the fill)."""
    alpha, foreground, behind = person_matte(image, person)
    share = alpha[..., None].astype(np.float64)
    trust = np.clip(1.0 - 2.0 * share, 0.0, 1.0)
    background = trust * behind + (1.0 - trust) * fill_background(image, alpha > 0, margin_px=1)
    background[alpha <= 0] = image[alpha <= 0]
    made_up = (image - (1.0 - share) * background) / np.maximum(share, 1e-6)
    foreground = np.where(share > 0, np.clip(np.rint(made_up), 0, 255), foreground).astype(np.uint8)
    return alpha, foreground, np.rint(background).astype(np.uint8)


def _person_layer(size: tuple[int, int], person: np.ndarray, face: np.ndarray, scale: float, turn: np.ndarray,
                  offset: np.ndarray, landmarks: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The grid over the person: rest vertices in head axes, their place in the photo, how much of the
    head's turn they follow, and the triangles over the person."""
    from scipy.interpolate import LinearNDInterpolator
    from scipy.ndimage import binary_dilation, binary_erosion
    from scipy.spatial import cKDTree

    height, width = size
    step = max(3.0, GRID_STEP * max(height, width))
    # where the photo's edge cuts the person (hair at the top, a shoulder at a side), the grid goes on past it,
    # its texture the edge's own: a turn or a nod brings more of the person into view, not the background
    reach = CUT_REACH_CM * scale
    top, bottom = (reach if person[0].any() else 0.0), (reach if person[-1].any() else 0.0)
    left, right = (reach if person[:, 0].any() else 0.0), (reach if person[:, -1].any() else 0.0)
    columns = np.linspace(-left, width + right, max(2, round((width + left + right) / step)) + 1)
    rows = np.linspace(-top, height + bottom, max(2, round((height + top + bottom) / step)) + 1)
    grid_x, grid_y = np.meshgrid(columns, rows)
    uv = np.column_stack([grid_x.ravel(), grid_y.ravel()])
    n_rows, n_columns = len(rows), len(columns)

    # depth: the face's own near its edge, the skull's front further out, the neck's plane lower down
    outline = list(face_outline())
    edge = face[outline]
    tree = cKDTree(edge[:, :2])
    inside = inside_polygon(uv, landmarks[outline, :2])
    surface = LinearNDInterpolator(face[:, :2], face[:, 2])
    vertices = np.zeros((len(uv), 3))
    photo_z = np.full(len(uv), offset[2])
    for _ in range(4):  # z such that the point lies on the surface wanted (a few fixed-point steps)
        points = np.column_stack([uv[:, 0], -uv[:, 1], photo_z])
        vertices = ((points - offset) @ turn) / scale
        distances, nearest = tree.query(vertices[:, :2], k=min(6, len(edge)))
        distance = distances[:, 0]
        # the outline's depth near each point, weighted smoothly (the nearest point's alone jumps where another
        # becomes nearest, and the grid folded along those lines under a turn)
        weights = np.exp(-(((distances - distance[:, None]) / EDGE_DEPTH_SPREAD_CM) ** 2))
        edge_z = (weights * edge[nearest, 2]).sum(axis=1) / weights.sum(axis=1)
        relative = (vertices[:, :2] - _SKULL_CENTRE[:2]) / _SKULL_RADII[:2]
        cover = 1.0 - (relative ** 2).sum(axis=1)
        skull = np.where(cover > 0, _SKULL_CENTRE[2] + _SKULL_RADII[2] * np.sqrt(np.clip(cover, 0, 1)),
                         _NECK_PLANE_Z)
        skull = _gentle(np.maximum(skull, _NECK_PLANE_Z).reshape(n_rows, n_columns), step / scale).ravel()
        blend = smoothstep(distance / 3.0)
        wanted = (1 - blend) * edge_z + blend * skull
        under = surface(vertices[:, :2])  # behind the face, which is drawn there, and moving as it does
        wanted = np.where(inside & np.isfinite(under), np.nan_to_num(under) - 0.3, wanted)
        photo_z = photo_z + scale * (wanted - vertices[:, 2]) / max(turn[2, 2], 0.5)
    points = np.column_stack([uv[:, 0], -uv[:, 1], photo_z])
    vertices = ((points - offset) @ turn) / scale

    chin_y = float(face[152, 1])
    weight = smoothstep((vertices[:, 1] - (chin_y - 4.5)) / 4.5)

    # triangles where the person is (grown by a cell, so the layer covers the filled background at rest)
    r = np.clip(((rows[:-1] + rows[1:]) / 2).astype(int), 0, height - 1)
    c = np.clip(((columns[:-1] + columns[1:]) / 2).astype(int), 0, width - 1)
    sample = person[np.ix_(r, c)]
    for dy in (0, 1):
        for dx in (0, 1):
            corner = person[np.ix_(np.clip(rows[dy:n_rows - 1 + dy].astype(int), 0, height - 1),
                                   np.clip(columns[dx:n_columns - 1 + dx].astype(int), 0, width - 1))]
            sample |= corner
    cells = binary_dilation(sample, iterations=2)
    # none over the mouth: its inside shows there, through the lips' opening (behind the eyes the grid stays,
    # under the eyeballs, so no background shows through the lids' corners)
    centres = np.column_stack([np.repeat((columns[:-1] + columns[1:])[None, :] / 2, n_rows - 1, axis=0).ravel(),
                               np.repeat((rows[:-1] + rows[1:])[:, None] / 2, n_columns - 1, axis=1).ravel()])
    mouth = LIP_OUTER_UPPER + LIP_OUTER_LOWER[::-1][1:-1]
    cells &= ~inside_polygon(centres, landmarks[list(mouth), :2]).reshape(cells.shape)
    # none deep under the face either (more than HIDDEN_UNDER_FACE_CM inside its outline, away from the eyes):
    # the face covers them in every pose (drawing them cost 5-7 % of a frame, and beside the nose's wings at 15
    # degrees of yaw a patch of them came through the face)
    margin = max(1, math.ceil(scale * HIDDEN_UNDER_FACE_CM / step))
    under = binary_erosion(inside_polygon(centres, landmarks[outline, :2]).reshape(cells.shape), iterations=margin)
    for upper, lower in (LIDS_LEFT, LIDS_RIGHT):
        eye = inside_polygon(centres, landmarks[list(upper + lower[::-1][1:-1]), :2]).reshape(cells.shape)
        under &= ~binary_dilation(eye, iterations=margin)
    cells &= ~under
    index = np.arange(n_rows * n_columns).reshape(n_rows, n_columns)
    a, b = index[:-1, :-1][cells], index[:-1, 1:][cells]
    d, e = index[1:, :-1][cells], index[1:, 1:][cells]
    layer_triangles = np.vstack([np.column_stack([a, d, b]), np.column_stack([b, d, e])])
    used = np.unique(layer_triangles)  # the grid's vertices off the person are never drawn: left out
    renumbered = np.full(len(uv), -1)
    renumbered[used] = np.arange(used.size)
    # past the photo's edge the grid's texture is the edge's own (the texture goes on below the photo with the
    # eyeballs' pictures, which a cell past the bottom edge showed as a grey wedge when the head tilted)
    texture_uv = np.clip(uv[used], 0.5, [width - 0.5, height - 0.5])
    return vertices[used], texture_uv, weight[used], renumbered[layer_triangles]


def _gentle(depth: np.ndarray, step_cm: float) -> np.ndarray:
    """``depth`` (cm, on a grid ``step_cm`` apart) raised where it falls off steeper than :data:`MAX_DEPTH_SLOPE`:
    the lowest surface at least as near as ``depth`` whose slope nowhere exceeds it (its upper cone envelope).
    A head's side drawn as steep as a skull's (the ellipsoid's rim) folds over itself under a turn of a few
    degrees, and the photo's hair showed there as a staircase of repeated strands."""
    from scipy.ndimage import grey_dilation

    # a cone step by step: each pass lets a point's depth reach its neighbours', less the slope times the
    # distance (the 8-neighbour metric, within 8 % of the straight one)
    reach = max(1, math.ceil(float(np.ptp(depth)) / MAX_DEPTH_SLOPE / step_cm))
    offsets = np.array([-1.0, 0.0, 1.0]) * step_cm
    cone = -MAX_DEPTH_SLOPE * np.hypot(*np.meshgrid(offsets, offsets))
    for _ in range(reach):
        depth = grey_dilation(depth, structure=cone, mode="nearest")
    return depth


# ---------------------------------------------------------------------------------------------------------
# drawing it


def photo_exposure(head: PhotoHead) -> float:
    """How bright the light on the face is in the photo beside the 3D head's skin colour (0.4-1.2): the mouth's
    inside, teeth and tongue are drawn that much darker or lighter, to sit in the photo's light.

    The light is read from the face's brighter skin (the :data:`EXPOSURE_PERCENTILE` th percentile of its
    landmarks' brightness): a beard, a moustache or a shadowed half of the face would darken a median, and grey
    the teeth of a well-lit face."""
    from .mesh import SKIN

    grey = np.array([0.299, 0.587, 0.114])
    at = np.clip(np.round(head.uv[:N_FACE_VERTICES]).astype(int), 0, [head.width - 1, head.height - 1])
    face = head.image[at[:, 1], at[:, 0]].astype(float) / 255.0
    lit = float(np.percentile(face @ grey, EXPOSURE_PERCENTILE))
    return float(np.clip(lit / (np.asarray(SKIN) @ grey), 0.4, 1.2))


class PhotoRenderer:
    """Frames of a :class:`PhotoHead`: the photo's framing, ``width`` pixels wide (default: the photo's).

    Parameters
    ----------
    head : PhotoHead
    width : int, optional
        Frame width in pixels (the height keeps the photo's proportions; both even).
    relight : bool
        Shade the photo's surfaces as they turn, the light staying where it was (default); False shows the
        texture as photographed in every pose.
    """

    def __init__(self, head: PhotoHead, width: int | None = None, *, relight: bool = True,
                 perspective: bool = True) -> None:
        from PIL import Image

        self.head = head
        self.width = head.width if width is None else int(width) + int(width) % 2
        self.zoom = self.width / head.width
        self.height = max(2, round(head.height * self.zoom / 2) * 2)
        self.supersample = PHOTO_SUPERSAMPLE
        self._canvas = Canvas(self.width, self.height, self.supersample)
        self._inside_canvas = Canvas(self.width, self.height, INSIDE_SUPERSAMPLE)
        mesh = head.rig.mesh
        drawn = np.isin(mesh.part, _TEXTURED_PARTS + _SHADED_PARTS)
        rig_triangles = mesh.triangles[drawn[mesh.triangles].all(axis=1)]
        textured_rig = np.isin(mesh.part[rig_triangles[:, 0]], _TEXTURED_PARTS)
        n_rig = mesh.n_vertices
        self.triangles = np.ascontiguousarray(np.vstack([rig_triangles, head.layer_triangles + n_rig]), np.int32)
        self.textured = np.concatenate([textured_rig, np.ones(len(head.layer_triangles), bool)])
        # the mouth's inside is seen through the lips' opening only, never through the skin round it
        self._behind = np.zeros(n_rig + len(head.layer_uv))
        self._behind[:n_rig][np.isin(mesh.part, _SHADED_PARTS)] = MOUTH_DEPTH_BIAS_CM * head.scale
        self._inside_vertices = np.flatnonzero(np.isin(mesh.part, _SHADED_PARTS))
        self.uv = np.vstack([head.uv, head.layer_uv])
        self.colors = np.vstack([mesh.colors.astype(np.float64), np.ones((len(head.layer_uv), 3))])
        # the mouth's inside as bright as the photo's light: its colours times the face's brightness in the
        # photo over the head's own skin's
        self.colors[:n_rig][np.isin(mesh.part, _SHADED_PARTS)] *= photo_exposure(head)
        # the photo with its coverage: round the person's outline the grid's cells show what is behind them
        rgba = head.texture_with_coverage().astype(np.float32) / 255.0
        rgba[:head.height, :head.width, 3] = head.coverage  # the coverage as computed, not rounded to a level
        self.texture = rgba
        background = Image.fromarray(head.background)
        if (self.width, self.height) != (head.width, head.height):
            background = background.resize((self.width, self.height), Image.Resampling.LANCZOS)
        self.background = np.asarray(background, np.float32) / 255.0
        # normals and light for the head's own triangles only: the person's grid is drawn as photographed
        self._rig_triangles = np.ascontiguousarray(rig_triangles)
        self._rig_rest = mesh.vertices.astype(np.float64)
        self._n_rig = n_rig
        self._normal_buffer = np.zeros((n_rig + len(head.layer_uv), 3))
        self.relight = relight
        self._pivot = head.to_photo(np.asarray([NECK_PIVOT], float))[0]
        self._layer_rest = head.to_photo(head.layer_vertices)
        # the person's grid near the face follows the face's skin (the jaw, the cheeks, the brows): each vertex
        # moves as the face vertices nearest it, fully within the face and fading out SKIN_FOLLOW_CM outside
        from scipy.spatial import cKDTree

        rest_face = mesh.vertices[:N_FACE_VERTICES].astype(float)
        distance, nearest = cKDTree(rest_face[:, :2]).query(head.layer_vertices[:, :2], k=4)
        inside = inside_polygon(head.layer_uv, head.uv[list(face_outline())])
        reach = np.where(inside, 1.0, 0.5 * (1 + np.cos(np.pi * np.clip(distance[:, 0] / SKIN_FOLLOW_CM, 0, 1))))
        weights = 1.0 / (distance + 0.05)
        weights *= (reach / weights.sum(axis=1))[:, None]
        self._skin = np.flatnonzero(reach > 0)
        self._skin_nearest, self._skin_weights = nearest[self._skin], weights[self._skin]
        self._follows = np.concatenate([mesh.turn_share(), head.layer_weight])
        self._turning = np.flatnonzero(self._follows > 0)
        self._lit = np.isin(mesh.part, _TEXTURED_PARTS)
        # the shading fades out towards the face's edge, where the face meets the unlit grid: no seam
        rest_xy = mesh.vertices[:N_FACE_VERTICES, :2].astype(float)
        edge = rest_xy[list(face_outline())]
        from_edge = np.min(np.linalg.norm(rest_xy[:, None, :] - edge[None, :, :], axis=2), axis=1)
        self._shading = np.ones(n_rig)
        self._shading[:N_FACE_VERTICES] = np.clip(from_edge / RELIGHT_FADE_CM, 0.0, 1.0)
        rest = self.vertices(np.zeros(N_FAPS))
        self._rest_normals = self._normals(rest)[:n_rig].copy()
        self._rest_light = self._light(self._rest_normals)
        self.perspective = perspective
        self._camera = np.array([head.width / 2, -head.height / 2, head.scale * CAMERA_DISTANCE_CM])
        self._rest_perspective = self._perspective(rest)
        self._rest_points = rest
        # the nearest point of the head is about a head's depth in front of its origin: depth stays positive
        self._far = float(head.scale * 60.0 + abs(head.offset[2])) * max(self.zoom, 1.0) * SUPERSAMPLE
        # the rest frame: a frame is drawn only where it can differ from it, round the triangles with a vertex
        # that a FAP moves (the head's turn, a field, the grid following the skin) or relights
        fields = np.abs(head.rig.fields).sum(axis=(0, 2))
        moves = np.concatenate([(fields > 0) | self._lit, np.zeros(len(head.layer_uv), bool)])
        moves[n_rig + self._skin] = True
        moves |= self._follows > 0
        self._movable = np.unique(self.triangles[moves[self.triangles].any(axis=1)])
        rest_xy = self._frame(np.zeros(N_FAPS))[0][self._movable, :2].copy()
        self._movable_rest = (rest_xy.min(axis=0), rest_xy.max(axis=0))
        self._rest_frame: np.ndarray | None = None
        self._rest_frame = self.render(np.zeros(N_FAPS), whole=True)

    def vertices(self, values: np.ndarray) -> np.ndarray:
        """Every drawn vertex (the head's, then the person layer's) in photo axes for one frame's values.

        The head turns about the neck by FAP 48-50 in the camera's axes, from the pose it has in the photo
        (that pose is its neutral one): a nod is about the picture's horizontal, whatever the photo's pose."""
        values = np.nan_to_num(np.asarray(values, float).reshape(N_FAPS))
        angles = [values[f - 1] * RADIANS_PER_AU for f in HEAD_FAPS]
        still = values.copy()
        still[[f - 1 for f in HEAD_FAPS]] = 0.0
        rig, head = self.head.rig, self.head
        points = np.empty((self._n_rig + len(self._layer_rest), 3))
        posing.pose(still, np.flatnonzero((still != 0) & rig.moving), rig.fields, self._rig_rest, head.scale,
                    head.rotation, head.offset, self._layer_rest, self._skin, self._skin_nearest, self._skin_weights,
                    self._turning, self._follows, self._pivot, bool(any(angles)), rotation(*angles), points)
        return points

    def _perspective(self, points: np.ndarray) -> np.ndarray:
        """Photo-axes points as a pinhole camera CAMERA_DISTANCE_CM in front of the picture sees them (x, y)."""
        centre_x, centre_y, distance = self._camera
        depth = distance / np.maximum(distance - points[:, 2], 1e-6 * distance)
        return np.column_stack([centre_x + (points[:, 0] - centre_x) * depth,
                                centre_y + (points[:, 1] - centre_y) * depth])

    @property
    def follows(self) -> np.ndarray:
        """float (n,): each drawn vertex's share of the head's turn."""
        return self._follows

    @property
    def pivot(self) -> np.ndarray:
        """The neck's pivot in the photo's axes (pixels)."""
        return self._pivot

    @property
    def behind_px(self) -> np.ndarray:
        """float (n,): how much further back each vertex is drawn (the mouth's inside), in the photo's pixels."""
        return self._behind

    @property
    def relit(self) -> tuple[np.ndarray, np.ndarray]:
        """How a turn relights each drawn vertex: its normal at rest (n, 3; in the photo's axes) and the share of
        its light change it shows (n; 0 where the turn relights nothing: the person's grid, the mouth's inside,
        which is lit by its own normals, and every vertex when ``relight`` is off)."""
        normals = np.zeros((len(self._follows), 3))
        share = np.zeros(len(self._follows))
        if self.relight:
            normals[:self._n_rig][self._lit] = self._rest_normals[self._lit]
            share[:self._n_rig][self._lit] = self._shading[self._lit]
        return normals, share

    def field(self, fap: int) -> np.ndarray:
        """float (n, 3): how every drawn vertex moves per unit of ``fap`` in the photo's axes (pixels), the person's
        grid following the face's skin (the head's turns, FAP 48-50, are not fields)."""
        head = self.head
        rig = head.scale * (head.rig.fields[fap - 1].astype(float) @ head.rotation.T)
        layer = np.zeros((len(head.layer_vertices), 3))
        if self._skin.size:
            layer[self._skin] = (rig[:N_FACE_VERTICES][self._skin_nearest] * self._skin_weights[..., None]).sum(axis=1)
        return np.vstack([rig, layer])

    def _turned_normals(self, values: np.ndarray) -> np.ndarray:
        """The lit vertices' rest normals turned as the head turns (each vertex by its share of the turn): a nod
        or a turn lights the face anew, but the skin's own stretching (a brow raised, the jaw opened) relights
        nothing, as the photo's own shading moves with the skin (lit by its stretched normals, the skin between
        a raised brow and the eye showed as a light smear)."""
        values = np.nan_to_num(values)
        angles = [values[f - 1] * RADIANS_PER_AU for f in HEAD_FAPS]
        rest = self._rest_normals[self._lit]
        if not any(angles):
            return rest
        share = self._follows[:self._n_rig][self._lit, None]
        mixed = rest + share * (rest @ rotation(*angles).T - rest)
        return mixed / np.maximum(np.linalg.norm(mixed, axis=1, keepdims=True), 1e-12)

    @staticmethod
    def _light(normals: np.ndarray) -> np.ndarray:
        """How much light a surface of these normals takes from a light above the camera, with ambient."""
        return RELIGHT_AMBIENT + (1 - RELIGHT_AMBIENT) * np.clip(normals @ RELIGHT_DIRECTION, 0.0, None)

    def _normals(self, points: np.ndarray) -> np.ndarray:
        """Vertex normals of the head's triangles (zero on the person's grid, which is not lit)."""
        posing.vertex_normals(points, self._rig_triangles, self._normal_buffer[:self._n_rig])
        return self._normal_buffer

    def render(self, values: np.ndarray, *, whole: bool = False) -> np.ndarray:
        """RGB uint8 (height, width, 3) of one frame's 68 FAP values (NaN and 0 are neutral).

        Only the part of the frame that can differ from the rest frame is drawn (the box round the triangles
        that a FAP can move or relight, where they are and where they were at rest); ``whole`` draws every
        pixel (the same image)."""
        values = np.asarray(values, float)
        if values.shape != (N_FAPS,):
            raise PhotoError(f"a head frame takes {N_FAPS} FAP values, got shape {values.shape}")
        screen, normals, colors = self._frame(values)
        window = None if whole else self._changed_window(screen)
        frame = rasterise_textured(screen, self.triangles, normals, colors, self.uv, self.textured, self.texture,
                                   self.background, factor=self.supersample, canvas=self._canvas, window=window,
                                   base=self._rest_frame)
        mouth = self._inside_window(screen, window)
        if mouth is None:
            return frame
        # the mouth's inside (drawn: thin teeth against the dark) with four samples a pixel; with one, a row of
        # teeth a pixel high showed as dashes
        fine = screen.copy()
        fine[:, :2] *= INSIDE_SUPERSAMPLE / self.supersample
        frame = rasterise_textured(fine, self.triangles, normals, colors, self.uv, self.textured, self.texture,
                                   self.background, factor=INSIDE_SUPERSAMPLE, canvas=self._inside_canvas,
                                   window=mouth, base=frame)
        return self._softened_inside(frame, mouth)

    def _inside_window(self, screen: np.ndarray,
                       window: tuple[int, int, int, int] | None) -> tuple[int, int, int, int] | None:
        """The pixel box (top, bottom, left, right) round the mouth's inside within ``window``, or None."""
        inside_xy = screen[self._inside_vertices, :2] / self.supersample
        top, bottom, left, right = window if window is not None else (0, self.height - 1, 0, self.width - 1)
        top, bottom = max(top, int(inside_xy[:, 1].min()) - 1, 0), min(bottom, int(inside_xy[:, 1].max()) + 1,
                                                                       self.height - 1)
        left, right = max(left, int(inside_xy[:, 0].min()) - 1, 0), min(right, int(inside_xy[:, 0].max()) + 1,
                                                                       self.width - 1)
        return None if top > bottom or left > right else (top, bottom, left, right)

    def _softened_inside(self, frame: np.ndarray, mouth: tuple[int, int, int, int]) -> np.ndarray:
        """The mouth's inside (drawn, not photographed) as soft as the photo: where it shows and a little round it,
        the frame blurred by :data:`INSIDE_SOFTNESS_PX`, so that its edges against the lips and the teeth's
        edges are no sharper than the photo's own."""
        from scipy.ndimage import gaussian_filter

        f = INSIDE_SUPERSAMPLE
        top, bottom, left, right = mouth
        nearest = self._inside_canvas.nearest[top * f:(bottom + 1) * f, left * f:(right + 1) * f]
        inside = (nearest >= 0) & ~self.textured[np.maximum(nearest, 0)]
        if not inside.any():
            return frame
        share = np.zeros((bottom - top + 1, right - left + 1), np.float32)  # each pixel's share of samples inside
        samples = inside.view(np.uint8)
        for row in range(f):
            for column in range(f):
                share += samples[row::f, column::f]
        share /= f * f
        sigma = INSIDE_SOFTNESS_PX * self.zoom
        margin = int(np.ceil(3 * sigma)) + 1
        rows, columns = np.nonzero(share)
        r0, r1 = max(rows.min() - margin, 0), min(rows.max() + margin + 1, share.shape[0])
        c0, c1 = max(columns.min() - margin, 0), min(columns.max() + margin + 1, share.shape[1])
        region = frame[top + r0:top + r1, left + c0:left + c1].astype(np.float32)
        weight = np.clip(2.0 * gaussian_filter(share[r0:r1, c0:c1], sigma, truncate=3.0), 0.0, 1.0)[..., None]
        blurred = gaussian_filter(region, (sigma, sigma, 0), truncate=3.0)
        frame[top + r0:top + r1, left + c0:left + c1] = np.rint(region + weight * (blurred - region)).astype(np.uint8)
        return frame

    def _frame(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The screen coordinates (samples and depth), normals and colours of every drawn vertex."""
        points = self.vertices(values)
        normals = self._normals(points)
        colors = self.colors
        if self.relight:
            # the light stays where it was when the photo was taken: a turned surface darkens or brightens by
            # its light now over its light then
            colors = colors.copy()
            now, then = self._light(self._turned_normals(values)), self._rest_light[self._lit]
            gain = np.clip(now / np.maximum(then, RELIGHT_AMBIENT), *RELIGHT_RANGE)
            share = self._shading[self._lit]
            colors[:self._n_rig][self._lit] = (1 + share * (gain - 1))[:, None]
        s = self.supersample * self.zoom
        if self.perspective:
            # as a camera at CAMERA_DISTANCE_CM would see the motion: what the turn changes in the perspective
            # view, laid over the photo's own (at rest the frame is the photo, pixel for pixel)
            points = points.copy()
            points[:, :2] = self._rest_points[:, :2] + self._perspective(points) - self._rest_perspective
        screen = np.column_stack([points[:, 0] * s, -points[:, 1] * s,
                                  self._far + (self._behind - points[:, 2]) * s])
        return screen, normals, colors

    def pixels(self, values: np.ndarray) -> np.ndarray:
        """Where every drawn vertex (the head's, then the person layer's) is in the frame of one frame's FAP
        values (68): x, y in pixels from the top-left corner."""
        return self._frame(np.asarray(values, float))[0][:, :2] / self.supersample

    def _changed_window(self, screen: np.ndarray) -> tuple[int, int, int, int]:
        """The pixel rows and columns (top, bottom, left, right) outside which the frame is the rest frame: the
        box round the triangles that any FAP can move or relight, where they are and where they were."""
        low_x, low_y, high_x, high_y = posing.bounds(screen, self._movable)
        low = np.minimum([low_x, low_y], self._movable_rest[0]) / self.supersample - 1
        high = np.maximum([high_x, high_y], self._movable_rest[1]) / self.supersample + 1
        return int(np.floor(low[1])), int(np.ceil(high[1])), int(np.floor(low[0])), int(np.ceil(high[0]))
