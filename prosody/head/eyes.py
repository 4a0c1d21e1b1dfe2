"""A photo head's eyes: each eyeball's own picture, so that raised lids and turned eyes uncover the eye.

In a photo, the part of an eyeball that the lids hide is the lids' skin: an eyeball textured by the photo alone
showed skin where a raised lid uncovered it (the eyes of fear and surprise did not widen) and where a turned eye
uncovered its corner. Each eyeball gets a picture of its own (:func:`eye_pictures`), placed below the photo in the
head's texture: the photo's own pixels wherever the eyeball shows at rest, and the white's and the iris's colours,
read from the photo, where the lids hide it. The landmarker puts the upper lid's line inside its lash line: the
lid is fitted a little lower (:func:`lashes_to_lids`), so a raised lid carries its lashes up with it.
"""

from __future__ import annotations

import numpy as np

from .mesh import EYE_LEFT, EYE_RIGHT, LIDS_LEFT, LIDS_RIGHT
from .person import inside_polygon

#: The upper lids' lash line lies partly inside the landmarks' lid line: the lid is fitted this share of the
#: eye's opening lower (at most 1.5 pixels), so the lashes go up with a raised lid instead of staying on the eye.
LASH_SHARE = 0.15
LASH_MAX_PX = 1.5
#: Outside the lids' opening an eyeball's picture blends from the photo's pixels into the white's and the iris's
#: colours over about this many pixels.
EYE_SEAM_PX = 1.0
#: An eye's white is drawn at most this much redder than blue (levels): where a photo shows too little of it,
#: its brightest pixels are the lids' skin's colour.
WHITE_WARMTH = 12.0


def lashes_to_lids(landmarks: np.ndarray) -> np.ndarray:
    """The landmarks with each upper lid's line (its corners apart) lowered by :data:`LASH_SHARE` of the eye's
    opening there (at most :data:`LASH_MAX_PX`): the landmarker puts the line inside the lashes' lower edge,
    and what lies above the line is the lid's, which carries it up when the lid is raised."""
    out = np.array(landmarks, float, copy=True)
    for upper, lower in (LIDS_LEFT, LIDS_RIGHT):
        for top, bottom in zip(upper[1:-1], lower[1:-1], strict=True):
            gap = max(0.0, float(landmarks[bottom, 1] - landmarks[top, 1]))
            out[top, 1] += min(LASH_SHARE * gap, LASH_MAX_PX)
    return out


def eye_pictures(image: np.ndarray, landmarks: np.ndarray, uv: np.ndarray,
                 part: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The head's texture (the photo and, below it, a picture of each eyeball, :func:`eye_picture`) and its
    vertices' places in it.

    Parameters
    ----------
    image : uint8 (height, width, 3)
    landmarks : float (478, 2+), the face's landmarks in the photo (pixels), the upper lids' lines as fitted
        (:func:`lashes_to_lids`).
    uv : float (n, 2), each vertex's place in the photo.
    part : int (n,), each vertex's part of the head (:data:`~.mesh.EYE_LEFT`, ...).

    Returns
    -------
    texture : uint8 (height + rows, width, 3)
    uv : float (n, 2), the eyeballs' vertices moved to their pictures.
    """
    height, width = image.shape[:2]
    uv = uv.copy()
    pictures = []
    column = 0
    for eye_part, lids, iris in ((EYE_LEFT, LIDS_LEFT, 473), (EYE_RIGHT, LIDS_RIGHT, 468)):
        vertices = np.flatnonzero(part == eye_part)
        low = np.maximum(np.floor(uv[vertices].min(axis=0)).astype(int) - 2, 0)
        high = np.minimum(np.ceil(uv[vertices].max(axis=0)).astype(int) + 3, [width, height])
        # the opening as the face's mesh draws it at rest (its lid rings' places), where the eyeball shows
        outline = uv[list(lids[0]) + list(lids[1][::-1][1:-1])]
        picture = eye_picture(image, landmarks, (low[0], low[1], high[0], high[1]), outline, iris)
        pictures.append((column, picture))
        uv[vertices] += np.array([column, height]) - low
        column += picture.shape[1] + 1
    texture = np.zeros((height + max(p.shape[0] for _, p in pictures), max(width, column), 3), np.uint8)
    texture[:height, :width] = image
    for left, picture in pictures:
        texture[height:height + picture.shape[0], left:left + picture.shape[1]] = picture
    return texture, uv


def eye_picture(image: np.ndarray, landmarks: np.ndarray, box: tuple[int, int, int, int],
                outline: np.ndarray, iris: int) -> np.ndarray:
    """uint8: the eyeball in ``box`` (left, top, right, bottom; pixels) as it would look with the lids open.

    Inside the lids' opening (``outline``: its corners, the upper lid's points and the lower's, in the photo's
    pixels, as the face is drawn at rest) and a pixel past it (three in front of the lower lid, where the eyeball
    shows at rest too), the photo; outside, the iris's colour within the iris's circle (MediaPipe's
    iris landmarks: ``iris`` its centre, the next four its edge) and the white's beyond, each the median of
    what the photo shows of it (the white: its brightest, greyest quarter, at most :data:`WHITE_WARMTH` redder
    than blue, not the lashes' shadow or the corners' skin),
    blending into the photo's own pixels over :data:`EYE_SEAM_PX` from the opening."""
    from scipy.ndimage import binary_dilation, binary_erosion, distance_transform_edt, gaussian_filter

    left, top, right, bottom = box
    crop = image[top:bottom, left:right].astype(np.float64)
    rows, columns = np.mgrid[top:bottom, left:right] + 0.5
    opening = inside_polygon(np.column_stack([columns.ravel(), rows.ravel()]), outline).reshape(crop.shape[:2])
    radius = float(np.mean(np.linalg.norm(landmarks[iris + 1:iris + 5, :2] - landmarks[iris, :2], axis=1)))
    in_iris = np.hypot(columns - landmarks[iris, 0], rows - landmarks[iris, 1]) <= radius
    clear = binary_erosion(opening, iterations=1)  # away from the lashes
    iris_seen, white_seen = crop[clear & in_iris], crop[clear & ~in_iris]
    iris_colour = np.median(iris_seen, axis=0) if len(iris_seen) >= 4 else np.full(3, 70.0)
    white_colour = np.full(3, 200.0)
    if len(white_seen) >= 4:
        # the white is bright and about grey; the lids' skin and the inner corner, seen beside it, are warm
        score = white_seen.sum(axis=1) - 6.0 * (white_seen[:, 0] - white_seen[:, 2])
        white_colour = np.median(white_seen[score >= np.percentile(score, 75)], axis=0)
        warmth = white_colour[0] - white_colour[2]
        if warmth > WHITE_WARMTH:  # too little of it seen: its brightest pixels, made nearly grey
            white_colour = white_colour.mean() + (white_colour - white_colour.mean()) * WHITE_WARMTH / warmth
    flat = np.where(in_iris[..., None], iris_colour, white_colour)
    if not opening.any():
        return np.clip(np.rint(flat), 0, 255).astype(np.uint8)
    # near the opening the photo's own pixels (away from the lashes), spread outwards (a normalised blur),
    # fading into the flat colours
    source = clear if clear.any() else opening
    weight = gaussian_filter(source.astype(float), EYE_SEAM_PX)
    spread = np.stack([gaussian_filter(crop[..., k] * source, EYE_SEAM_PX) for k in range(3)], axis=-1)
    spread /= np.maximum(weight, 1e-9)[..., None]
    near = np.exp(-distance_transform_edt(~opening) / EYE_SEAM_PX)[..., None]
    outside = near * spread + (1 - near) * flat
    # the photo a pixel past the opening, and further below the corners' line: at rest the eyeball shows there
    # too, in front of the lower lid's skin
    (x0, y0), (x1, y1) = outline[0], outline[len(outline) // 2]  # the corners
    below = rows > y0 + (y1 - y0) * (columns - x0) / ((x1 - x0) or 1.0)
    kept = binary_dilation(opening, iterations=1) | (binary_dilation(opening, iterations=3) & below)
    return np.clip(np.rint(np.where(kept[..., None], crop, outside)), 0, 255).astype(np.uint8)
