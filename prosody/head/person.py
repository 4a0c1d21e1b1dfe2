"""The person in a photo told from the background, and the background filled in behind them.

A photo head moves the person (hair, ears, neck, shoulders) and not what is behind them, so it needs to know
which pixels are the person's. MediaPipe's selfie segmentation model (Apache-2.0; the file
``data/selfie_segmentation.tflite``, as the PyPI wheel of ``mediapipe`` 0.10.14 ships it, its SHA-256 checked;
``python -m scripts.segmentation_model`` writes it again) gives each pixel the chance that it is a person's. Its
outline is drawn at 256 x 256, so its edge can be off by a few of the photo's pixels: OpenCV's GrabCut places the
edge by the photo's colours within a narrow band round it (:data:`MASK_BAND`), the person's and the background's
colours learnt from either side. Both run on the CPU in a fraction of a second; MediaPipe (the ``track`` extra)
already finds the face.

Before the model, GrabCut alone, started from the face and head-and-shoulder shapes round it, left out hair
whose colour was near the background's (Katie Hill's hair on her left, Amy Klobuchar's) and took in backdrops
near the clothes' (a red studio wall): a turned head then uncovered a smear where hair had been.

Along the outline a pixel is part person, part background (wisps of hair, a blurred edge). The matte
(:func:`person_matte`) tells how much of each is the person's and what colour the person and the background are
there, so the person moves without the background's colour round their edge: closed-form matting (Levin,
Lischinski and Weiss 2008) in a band round the outline, and the multilevel foreground and background estimation
of Germer et al. (2020), both from the PyPI package ``pymatting``.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np

from ..errors import PhotoError
from .landmarks import INSTALL_HINT, checked_file, quiet_native_logs

#: MediaPipe's selfie segmentation model (general, 256 x 256 input), from the PyPI wheel of mediapipe 0.10.14.
SEGMENTATION_MODEL = Path(__file__).resolve().parent / "data" / "selfie_segmentation.tflite"
SEGMENTATION_SHA256 = "9ee168ec7c8f2a16c56fe8e1cfbc514974cbbb7e434051b455635f1bd1462f5c"
#: The longer side of the copy GrabCut works on, pixels.
MASK_WORK_PX = 400
#: GrabCut may move the model's outline by this share of the photo's longer side either way (8 pixels of 400):
#: the model's edge is drawn at 256 x 256, a few pixels coarse.
MASK_BAND = 1 / 50
#: A pixel is the person's where the model's chance is at least this (before GrabCut's refinement).
PERSON_CHANCE = 0.5
#: The matte is worked out this far either side of the person's outline (a share of the photo's longer side: 6
#: pixels of 512), and at most :data:`MATTE_BAND_MAX_PX`; nearer the person it is 1, further out 0. Its cost
#: grows with the band: on a 1920 x 1080 photo 23 pixels took 3 s.
MATTE_BAND = 1 / 85
MATTE_BAND_MAX_PX = 8


def _cv2():
    try:
        import cv2
    except ImportError:
        raise PhotoError(f"a photo head needs OpenCV, which comes with MediaPipe: {INSTALL_HINT}") from None
    return cv2


def segmentation_model_path() -> str:
    """Path of the segmentation model, checked against :data:`SEGMENTATION_SHA256`.

    Raises
    ------
    PhotoError
        The file is missing or not the expected one.
    """
    return checked_file(SEGMENTATION_MODEL, SEGMENTATION_SHA256, what="the person segmentation model",
                        remedy="reinstall the package", error=PhotoError)


def person_chance(image: np.ndarray) -> np.ndarray:
    """float32 (height, width), 0..1: each pixel's chance of being a person's, by MediaPipe's selfie
    segmentation model, for an RGB uint8 image (height, width, 3)."""
    path = segmentation_model_path()
    with quiet_native_logs():
        try:
            import mediapipe
            from mediapipe.tasks.python import BaseOptions, vision
        except ImportError:
            raise PhotoError(f"a photo head needs MediaPipe: {INSTALL_HINT}") from None
        options = vision.ImageSegmenterOptions(base_options=BaseOptions(model_asset_path=path),
                                               output_confidence_masks=True, output_category_mask=False)
        segmenter = vision.ImageSegmenter.create_from_options(options)
    try:
        picture = mediapipe.Image(image_format=mediapipe.ImageFormat.SRGB,
                                  data=np.ascontiguousarray(image[..., :3], np.uint8))
        chance = np.array(segmenter.segment(picture).confidence_masks[0].numpy_view(), np.float32)
    finally:
        segmenter.close()
    return chance.reshape(image.shape[:2])


def person_mask(image: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
    """bool (height, width): the person (face, hair, ears, neck, shoulders) in an RGB uint8 photo whose face
    has these landmarks (478, 2+; pixels).

    The segmentation model's person (:func:`person_chance`), its edge placed by GrabCut within
    :data:`MASK_BAND` of it; the face itself is always the person's. Where the model sees no person on the face
    (a drawing, a statue), GrabCut starts from head-and-shoulder shapes round the face instead. The largest
    piece joined to the face is kept, its holes closed."""
    cv2 = _cv2()
    height, width = image.shape[:2]
    factor = min(1.0, MASK_WORK_PX / max(height, width))  # GrabCut on a small copy: its cost grows with the pixels
    size = (max(8, round(width * factor)), max(8, round(height * factor)))
    small = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    chance = cv2.resize(person_chance(image), size, interpolation=cv2.INTER_AREA)
    points = landmarks[:468, :2] * factor
    face = np.zeros(small.shape[:2], np.uint8)
    cv2.fillConvexPoly(face, cv2.convexHull(points.astype(np.float32)).astype(np.int32), 1)
    person = chance >= PERSON_CHANCE
    if person[face > 0].mean() >= 0.5:
        band = max(2, round(MASK_BAND * max(size)))
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * band + 1, 2 * band + 1))
        mask = np.where(person, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
        mask[cv2.erode(person.astype(np.uint8), kernel) > 0] = cv2.GC_FGD
        mask[cv2.erode((~person).astype(np.uint8), kernel) > 0] = cv2.GC_BGD
    else:
        mask = _shape_prior(cv2, small.shape[:2], points)
    mask[face > 0] = cv2.GC_FGD
    bgd, fgd = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.setRNGSeed(0)  # GrabCut's k-means starts from OpenCV's generator: the same mask each time
    try:
        cv2.grabCut(cv2.cvtColor(small, cv2.COLOR_RGB2BGR), mask, None, bgd, fgd, 4, cv2.GC_INIT_WITH_MASK)
    except cv2.error:  # one colour on a side (a flat backdrop): the mask stays as started
        pass
    found = np.isin(mask, (cv2.GC_FGD, cv2.GC_PR_FGD)).astype(np.uint8)
    centre = points.mean(axis=0)
    count, labels = cv2.connectedComponents(found)
    if count > 2:
        centre_label = labels[int(np.clip(centre[1], 0, size[1] - 1)), int(np.clip(centre[0], 0, size[0] - 1))]
        if centre_label:
            found = (labels == centre_label).astype(np.uint8)
    found = cv2.morphologyEx(found, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5)))
    return cv2.resize(found, (width, height), interpolation=cv2.INTER_LINEAR) > 0


def _shape_prior(cv2, shape: tuple[int, int], points: np.ndarray) -> np.ndarray:
    """GrabCut's start where the model sees no person: the head (an ellipse round the face) and the shoulders
    below it likely the person's, the neck under the chin certain, the sides beside the head and the top row the
    background's."""
    face_w, face_h = float(np.ptp(points[:, 0])), float(np.ptp(points[:, 1]))
    centre = points.mean(axis=0)
    chin_y = float(points[152, 1])
    rows, columns = np.mgrid[0:shape[0], 0:shape[1]]
    mask = np.full(shape, cv2.GC_PR_BGD, np.uint8)
    head = (((columns - centre[0]) / (0.85 * face_w)) ** 2
            + ((rows - (centre[1] - 0.12 * face_h)) / (0.92 * face_h)) ** 2) <= 1.0
    body = (rows > chin_y - 0.1 * face_h) & (np.abs(columns - centre[0]) <= 0.33 * face_w
                                             + np.maximum(rows - chin_y, 0) * 2.0)
    mask[head | body] = cv2.GC_PR_FGD
    mask[(np.abs(columns - centre[0]) > 1.6 * face_w) & (rows < chin_y)] = cv2.GC_BGD
    top = max(1, round(0.02 * shape[0]))
    mask[:top] = np.where(head[:top], mask[:top], cv2.GC_BGD)
    # the neck and the chest right under the chin are the person too (their colours teach GrabCut the clothes')
    neck = (rows > chin_y + 0.05 * face_h) & (rows < chin_y + 0.8 * face_h) & (np.abs(columns - centre[0])
                                                                              < 0.22 * face_w)
    mask[neck] = cv2.GC_FGD
    return mask


def fill_background(image: np.ndarray, person: np.ndarray, *, margin_px: int) -> np.ndarray:
    """The photo with the person (grown by ``margin_px``) filled in from the background round it: normalised
    convolution (a Gaussian average of the background pixels alone), at the finest of a few widths where
    enough background is near, so the fill is the surrounding background blurred, without streaks."""
    from scipy.ndimage import binary_dilation, gaussian_filter, zoom

    height, width = image.shape[:2]
    grown = binary_dilation(person, iterations=max(1, margin_px))
    factor = min(1.0, 256.0 / max(height, width))  # the fill is smooth: worked out on a small copy
    small_size = (max(8, round(height * factor)), max(8, round(width * factor)))
    small = np.stack([zoom(image[..., k].astype(np.float64), (small_size[0] / height, small_size[1] / width),
                           order=1) for k in range(3)], axis=-1)
    known = zoom(1.0 - grown.astype(np.float64), (small_size[0] / height, small_size[1] / width), order=1)
    known = (known > 0.99).astype(np.float64)
    # coarsest first, each finer width laid over it where it has background enough (blended, no edges)
    filled = np.broadcast_to(image.reshape(-1, 3).mean(axis=0), small.shape).astype(np.float64)
    side = max(small_size)

    def blurred(plane: np.ndarray, sigma: float) -> np.ndarray:
        # a wide blur is smooth: worked out on a copy as many times smaller as it is wider than 4 pixels
        step = max(1, int(sigma // 4))
        if step == 1:
            return gaussian_filter(plane, sigma, mode="nearest")
        shrunk = zoom(plane, 1 / step, order=1, grid_mode=True, mode="nearest")
        out = gaussian_filter(shrunk, sigma / step, mode="nearest")
        return zoom(out, np.divide(plane.shape, out.shape), order=1, grid_mode=True, mode="nearest")

    for sigma in (1.0 * side, 0.3 * side, 0.12 * side, 0.05 * side, 0.02 * side):
        weight = blurred(known, sigma)
        values = np.stack([blurred(small[..., k] * known, sigma) for k in range(3)], -1)
        alpha = np.clip((weight - 0.05) / 0.25, 0.0, 1.0)[..., None]
        filled = alpha * values / np.maximum(weight, 1e-9)[..., None] + (1 - alpha) * filled
    full = np.stack([zoom(filled[..., k], (height / small_size[0], width / small_size[1]), order=1)
                     for k in range(3)], axis=-1)[:height, :width]
    out = image.copy()
    out[grown] = np.clip(full[grown] + 0.5, 0, 255).astype(np.uint8)
    return out


# ---------------------------------------------------------------------------------------------------------
# building the photo head



def person_matte(image: np.ndarray, person: np.ndarray, band_px: int | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How much of each pixel is the person's, and the person's and the background's colours there.

    Parameters
    ----------
    image : uint8 (height, width, 3)
    person : bool (height, width), the person's pixels (:func:`person_mask`).
    band_px : int, optional
        The matte is worked out this far outside the outline and a third of it inside; 1 nearer the person, 0
        further out. Default: :data:`MATTE_BAND` of the image's longer side, 2 to :data:`MATTE_BAND_MAX_PX`.

    Returns
    -------
    alpha : float32 (height, width), 0..1
    foreground : uint8 (height, width, 3), the person's colour (the photo's where ``alpha`` is 1)
    background : uint8 (height, width, 3), the background's colour (the photo's where ``alpha`` is 0)
    """
    from scipy.ndimage import binary_dilation, binary_erosion

    try:
        from pymatting import estimate_alpha_cf, estimate_foreground_ml
    except ImportError:
        raise PhotoError(f"a photo head needs pymatting: {INSTALL_HINT}") from None
    if band_px is None:
        band_px = min(MATTE_BAND_MAX_PX, max(2, round(MATTE_BAND * max(image.shape[:2]))))
    band = max(1, int(band_px))
    # inside the outline the band is a third as wide: the outline is placed on the photo's colours already, and a
    # thin part of the person (an ear) wholly within the band was matted out as background
    sure = binary_erosion(person, iterations=max(1, band // 3), border_value=1)
    unsure = binary_dilation(person, iterations=band) & ~sure
    alpha = person.astype(np.float64)
    foreground = background = image.astype(np.float64) / 255.0
    if unsure.any() and sure.any():
        # worked out in the box round the band only (a pixel further out is all person or all background)
        rows, columns = np.flatnonzero(unsure.any(axis=1)), np.flatnonzero(unsure.any(axis=0))
        box = (slice(max(rows[0] - 2, 0), rows[-1] + 3), slice(max(columns[0] - 2, 0), columns[-1] + 3))
        rgb = foreground[box]
        trimap = np.where(sure[box], 1.0, np.where(unsure[box], 0.5, 0.0))
        # its solver's preconditioner prints to standard output each time it retries with a larger shift
        # (a flat backdrop makes the system nearly singular): the command's own output stays clean
        with contextlib.redirect_stdout(io.StringIO()):
            try:
                alpha[box] = np.clip(estimate_alpha_cf(rgb, trimap), 0.0, 1.0)
            except ValueError:  # no shift helped: the outline as it is, hard
                pass
        foreground, background = foreground.copy(), background.copy()
        foreground[box], background[box] = estimate_foreground_ml(rgb, alpha[box], return_background=True)

    def colours(values: np.ndarray, keep: np.ndarray) -> np.ndarray:
        out = np.clip(np.rint(values * 255.0), 0, 255).astype(np.uint8)
        out[keep] = image[keep]  # the photo itself where the pixel is all the person's (or all background)
        return out

    return alpha.astype(np.float32), colours(foreground, alpha >= 1.0), colours(background, alpha <= 0.0)


def inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """bool (n,): which of the points (n, 2) lie inside the polygon (m, 2)."""
    from matplotlib.path import Path as Polygon

    return Polygon(polygon).contains_points(points)
