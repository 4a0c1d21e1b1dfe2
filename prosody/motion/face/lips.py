"""Lips from phones: MPEG-4 visemes coarticulated by dominance functions (Wu et al. 2006, after Cohen and Massaro 1993).

Each phone belongs to one of the 14 MPEG-4 visemes (plus neutral, 0). A viseme is a mouth shape given by
three numbers, which are turned into low-level lip FAPs by one fixed geometry (:func:`shape_faps`):

- ``opening``: inner-lip separation in MNS (mouth-nose separation / 1024). It is shared by the jaw (FAP 3,
  60 %), the top lip going up (FAP 4, 15 %) and the bottom lip going down (FAP 5, 25 %), so that
  ``FAP 3 - FAP 4 - FAP 5`` is the opening; the lips' mid-left and mid-right points (8-11) follow the middle by
  80 %, and the outer lip contour (51-58) follows the inner one;
- ``rounding``: lip protrusion, 0..1 (FAP 16, 17: 300 MNS at 1);
- ``spread``: change of mouth width as a fraction of its rest width (each inner and outer corner, FAP 6, 7,
  53, 54, moves by half of it: ``512 * spread`` MW).

The shapes in :data:`VISEMES` were set from phonetic descriptions of the visemes (open vowels widest, /i/ and
/e/ spread, /o/, /u/, /r/ and the postalveolars rounded, bilabials closed, the neutral face's mouth closed as
MPEG-4 defines it); their openings are now fitted by least squares to the video-tracked mouths of 35 speakers
(``experiments/viseme_fit.py``), each phone its own (``Viseme.phone_openings``: a schwa opens less than an /aa/
of the same viseme), silence and /p b m/ held closed and every other phone but /f v/ held at least
:data:`MIN_OPEN_MNS` apart. Held out by speaker, the fitted openings follow people's mouths better than the
hand-set ones did (see that experiment); rounding and spread stay as set by hand, one a viseme. Tracked openings
are measured in outer-eye-corner widths; the conversion takes the mouth-nose separation as 0.22 of that width
(adult proportions).

Coarticulation (:func:`blend`): every phone segment ``i`` has a dominance over time

    D_i(t) = alpha_i * exp(-theta_i * d_i(t) ** c)

where ``d_i(t)`` is the distance from ``t`` to the segment (0 inside it, so a long segment holds its shape;
for a segment of no length this is the Cohen-Massaro form about its centre), with ``theta`` before the
segment (anticipation) and after it (carry-over) given separately. Each parameter track is then
``F(t) = sum_i D_i(t) T_i / sum_i D_i(t)``, which stays within the targets' range. Bilabials and labiodentals
are dominant (large ``alpha``) and sharp (large ``theta``), so a /p/ closes the lips whatever its neighbours,
while a vowel lends its shape to the consonants around it.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from ...fap.table import Fap

#: Lip FAPs this module writes.
#: Ways of making lips: from recognised phones (visemes, the default), from the spectrum (acoustic), or both
#: (combined: their mean, the visemes' closures kept).
LIP_METHODS = ("visemes", "acoustic", "combined")
LIP_FAPS = (3, 4, 5, 6, 7, 8, 9, 10, 11, 16, 17, 51, 52, 53, 54, 55, 56, 57, 58)
#: MPEG-4's high-level viseme FAP: lips made from phones also carry the number of the viseme said at each frame
#: (its ``viseme_select1``), which mouth cues read (``prosody.fap.mouth_cues``). The .fap writer leaves it out,
#: as it does every high-level FAP, and nothing draws it: the low-level lip FAPs show it.
VISEME_FAP = int(Fap.VISEME)
#: Inner-lip FAP -> the outer-lip FAP that follows it.
OUTER_OF_INNER = {4: 51, 5: 52, 6: 53, 7: 54, 8: 55, 9: 56, 10: 57, 11: 58, 12: 59, 13: 60}
#: Shares of the opening taken by the jaw (FAP 3), the top lip (FAP 4, up: negative) and the bottom lip
#: (FAP 5, down: negative).
OPENING_SHARES = {3: 0.60, 4: -0.15, 5: -0.25}
#: How much the lips' mid-left and mid-right points follow the middle.
MIDPOINT_FOLLOW = 0.8
#: Protrusion of each lip at rounding 1, MNS.
PROTRUSION_MNS = 300.0
#: Mouth-nose separation as a fraction of the outer eye-corner distance (to convert tracked openings).
MNS_PER_EYE_WIDTH = 0.22


@dataclass(frozen=True)
class Viseme:
    """One MPEG-4 viseme: its phones, its mouth shape and its dominance.

    Parameters
    ----------
    number : int in 0..14
        The MPEG-4 viseme number (0: neutral).
    name : str
    phones : tuple of str
        ARPAbet phones shown by it.
    opening : float >= 0, in MNS
        The viseme's opening (its phones' where ``phone_openings`` does not give their own).
    rounding : float
        Protrusion, 0 (none) to 1.
    spread : float
        Width change, fraction of the rest width (negative: narrower).
    alpha : float > 0
        Dominance magnitude.
    theta_before_s, theta_after_s : float > 0, in 1/s
        Rate of decay of the dominance before and after the segment.
    phone_openings : tuple of float >= 0, optional
        Each of ``phones``' own opening, in MNS (Cohen and Massaro give each segment its own targets: a schwa
        opens less than an /aa/ of the same viseme).
    """

    number: int
    name: str
    phones: tuple[str, ...]
    opening: float
    rounding: float
    spread: float
    alpha: float
    theta_before: float
    theta_after: float
    phone_openings: tuple[float, ...] | None = None

    def opening_of(self, phone: str) -> float:
        """The opening of one of its phones (ARPAbet, without stress), in MNS."""
        if self.phone_openings is not None and phone in self.phones:
            return self.phone_openings[self.phones.index(phone)]
        return self.opening


#: Exponent ``c`` of the dominance functions (1: exponential, as Cohen and Massaro's default).
DOMINANCE_EXPONENT = 1.0

# Openings in MNS, fitted by least squares to the tracked mouths of the talking videos (30 speakers) and the
# talking-heads clips (5 speakers) on the phones recognised without a transcript, each clip aligned by its own
# sound-to-picture lag; silence and /p b m/ held closed, every other phone but /f v/ at least MIN_OPEN_MNS
# (``experiments/viseme_fit.py``): each phone's own opening (``phone_openings``, as Cohen and Massaro give each
# segment its own targets), and the viseme's, fitted as one opening a viseme. Held out by speaker, the phones'
# openings raise the mouth-opening r from 0.318 (the hand-set openings) to 0.378 on the videos and from 0.356 to
# 0.432 on the talking heads; one opening a viseme gives 0.358 and 0.396. The fit opens a schwa (AH) half as far
# as /aa ae ay/, /e/ nearly as far as /a/, /o/ less than /e/, and /th/, /n l/, /r/ and /uw w/ barely; /h/ as
# wide as anything (908 MNS: likely where the phone loop hears breath as the mouth opens before speech). The
# hand-set openings they replace (MNS, times 1.75: /a/ 578, /e/ 455, /o/ 490, /i/ and /k g/ 332, /u/ 298, the
# other consonants 192-280, /f v/ 79) gave a closer /e/ and a wider /o/ and /u/.
# Rounding and spread are set by hand from phonetic descriptions. Dominance: vowels 1 at 12/s (anticipation
# 9/s), consonants 0.6 at 15/s, silence 0.8 at 10/s; labiodentals 6 at 40/s; bilabials 50 at 80/s, so that a
# 30 ms /p/ between two open vowels closes the lips to a thirtieth of their opening (22 MNS between two /a/):
# with 10 at 60/s it left a seventh. On the talking-heads clips that choice left the opening r as it was and lifted the
# closure F1 from 0.27 to 0.31.
VISEMES: tuple[Viseme, ...] = (
    Viseme(0, "neutral", ("SIL",), 0.0, 0.00, 0.000, 0.8, 10.0, 10.0, (0.0,)),
    Viseme(1, "p_b_m", ("P", "B", "M"), 0.0, 0.02, -0.010, 50.0, 80.0, 80.0, (0.0, 0.0, 0.0)),
    Viseme(2, "f_v", ("F", "V"), 122.0, 0.00, -0.010, 6.0, 40.0, 40.0, (63.0, 169.0)),
    Viseme(3, "th_dh", ("TH", "DH"), 150.0, -0.02, 0.010, 0.6, 15.0, 15.0, (150.0, 250.0)),
    Viseme(4, "t_d", ("T", "D"), 329.0, -0.02, 0.010, 0.6, 15.0, 15.0, (321.0, 297.0)),
    Viseme(5, "k_g", ("K", "G", "NG", "HH"), 485.0, -0.01, 0.010, 0.6, 15.0, 15.0, (384.0, 187.0, 293.0, 991.0)),
    Viseme(6, "ch_jh_sh", ("CH", "JH", "SH", "ZH"), 271.0, 0.15, -0.030, 0.6, 15.0, 15.0,
           (150.0, 246.0, 368.0, 495.0)),
    Viseme(7, "s_z", ("S", "Z"), 288.0, -0.02, 0.010, 0.6, 15.0, 15.0, (372.0, 254.0)),
    Viseme(8, "n_l", ("N", "L"), 209.0, -0.01, 0.010, 0.6, 15.0, 15.0, (203.0, 190.0)),
    Viseme(9, "r", ("R", "ER"), 236.0, 0.10, -0.020, 0.6, 15.0, 15.0, (150.0, 293.0)),
    Viseme(10, "a", ("AA", "AE", "AH", "AW", "AY"), 672.0, -0.02, 0.020, 1.0, 9.0, 12.0,
           (752.0, 834.0, 336.0, 535.0, 730.0)),
    Viseme(11, "e", ("EH", "EY"), 604.0, -0.03, 0.030, 1.0, 9.0, 12.0, (558.0, 668.0)),
    Viseme(12, "i", ("IH", "IY", "Y"), 426.0, -0.04, 0.040, 1.0, 9.0, 12.0, (429.0, 438.0, 369.0)),
    Viseme(13, "o", ("AO", "OW", "OY"), 383.0, 0.12, -0.030, 1.0, 9.0, 12.0, (564.0, 288.0, 407.0)),
    Viseme(14, "u", ("UH", "UW", "W"), 150.0, 0.20, -0.050, 1.0, 9.0, 12.0, (313.0, 150.0, 150.0)),
)
#: The least opening of a viseme that keeps the lips apart (MNS; about 3 mm): every viseme but silence, /p b m/
#: and /f v/ (the lower lip under the teeth) opens at least this far, in the fit of the openings too.
MIN_OPEN_MNS = 150.0
#: Every phone of the visemes, in their order: the columns of :func:`phone_weights`.
PHONE_ORDER: tuple[str, ...] = tuple(phone for viseme in VISEMES for phone in viseme.phones)
#: ARPAbet phone (or SIL) -> its viseme.
VISEME_OF_PHONE: dict[str, Viseme] = {phone: viseme for viseme in VISEMES for phone in viseme.phones}


def viseme_of(phone: str) -> Viseme:
    """The viseme of an ARPAbet phone (stress digits ignored); unknown labels are silence.

    Examples
    --------
    >>> viseme_of("M").name, viseme_of("AY1").number, viseme_of("<noise>").name
    ('p_b_m', 10, 'neutral')
    """
    return VISEME_OF_PHONE.get(_arpabet(phone), VISEMES[0])


def _arpabet(label: str) -> str:
    """A phone's label as the visemes list it: upper case, without stress digits."""
    return "".join(ch for ch in label.upper() if ch.isalpha())


def dominance(times_s: np.ndarray, *, start_s: float, end_s: float, alpha: float, theta_before: float,
              theta_after: float, exponent: float = DOMINANCE_EXPONENT) -> np.ndarray:
    """Dominance of one segment over ``times_s``: ``alpha * exp(-theta * d ** c)``, ``d`` the distance to
    ``[start_s, end_s]`` (``theta_before`` before it, ``theta_after`` after it).

    Examples
    --------
    >>> dominance(np.array([0.0, 0.5, 1.0]), start_s=0.5, end_s=0.5, alpha=1.0, theta_before=10.0,
    ...           theta_after=10.0).round(5)
    array([0.00674, 1.     , 0.00674])
    """
    before = np.clip(start_s - times_s, 0.0, None)
    after = np.clip(times_s - end_s, 0.0, None)
    return alpha * np.exp(-(theta_before * before**exponent + theta_after * after**exponent))


def blend(times_s: np.ndarray, segments: Sequence[tuple[float, float]], targets: np.ndarray, *,
          alphas: Sequence[float], thetas_before: Sequence[float], thetas_after: Sequence[float],
          exponent: float = DOMINANCE_EXPONENT) -> np.ndarray:
    """Targets blended by their segments' dominance: ``sum D_i T_i / sum D_i`` at every time.

    Parameters
    ----------
    times_s : array of shape (n,)
    segments : sequence of (start_s, end_s)
    targets : array of shape (n_segments,) or (n_segments, k)
    alphas, thetas_before, thetas_after : sequences of n_segments floats > 0

    Returns
    -------
    array of shape (n,) or (n, k)

    Examples
    --------
    Two segments with targets 0 and 100, centres 0.5 s apart, theta 10/s:

    >>> blend(np.array([0.25, 0.5]), [(0.0, 0.0), (0.5, 0.5)], np.array([0.0, 100.0]), alphas=[1, 1],
    ...       thetas_before=[10, 10], thetas_after=[10, 10]).round(3)
    array([50.   , 99.331])
    """
    targets = np.asarray(targets, dtype=float)
    if len(segments) == 0 or targets.shape[0] != len(segments):
        raise ConfigError(f"need one target per segment, got {targets.shape[0]} targets for {len(segments)} segments")
    times_s = np.asarray(times_s, dtype=float)
    flat = targets.reshape(len(segments), -1)
    numerator = np.zeros((times_s.size, flat.shape[1]))
    total = np.zeros(times_s.size)
    ordered = bool(np.all(np.diff(times_s) >= 0))
    for i, (start, end) in enumerate(segments):
        # a segment's dominance is read where it is above exp(-40) of its peak (all of it if the times are
        # not in order): the sum over thousands of phones stays linear in the recording's length
        lo, hi = 0, times_s.size
        if ordered and exponent > 0:
            reach_before = (40.0 / thetas_before[i]) ** (1 / exponent)
            reach_after = (40.0 / thetas_after[i]) ** (1 / exponent)
            lo, hi = np.searchsorted(times_s, [start - reach_before, end + reach_after], side="left")
        if hi <= lo:
            continue
        weight = dominance(times_s[lo:hi], start_s=start, end_s=end, alpha=alphas[i],
                           theta_before=thetas_before[i], theta_after=thetas_after[i], exponent=exponent)
        total[lo:hi] += weight
        numerator[lo:hi] += weight[:, None] * flat[i]
    # far from every segment all dominances vanish: the nearest segment's target then holds
    empty = total <= 1e-300
    if empty.any():
        centres = np.array([0.5 * (a + b) for a, b in segments])
        nearest = np.abs(times_s[empty, None] - centres[None, :]).argmin(axis=1)
        numerator[empty] = flat[nearest]
        total[empty] = 1.0
    out = numerator / total[:, None]
    return out.reshape((times_s.size, *targets.shape[1:]))


def _spoken(phones: Sequence, visemes: Sequence[Viseme]) -> list[tuple[Viseme, str]]:
    """Each phone's viseme in ``visemes`` (by MPEG-4 number) and its label without stress."""
    lookup = {phone: viseme for viseme in visemes for phone in viseme.phones}
    spoken = []
    for phone in phones:
        label = _arpabet(phone.label)
        spoken.append((lookup.get(viseme_of(label).phones[0], visemes[0]), label))
    return spoken


def _blended(times_s: np.ndarray, phones: Sequence, spoken: list[tuple[Viseme, str]], targets: np.ndarray):
    chosen = [viseme for viseme, _ in spoken]
    return blend(times_s, [(p.start_s, p.end_s) for p in phones], targets, alphas=[v.alpha for v in chosen],
                 thetas_before=[v.theta_before for v in chosen], thetas_after=[v.theta_after for v in chosen])


def viseme_weights(times_s: np.ndarray, phones: Sequence, *, visemes: Sequence[Viseme] | None = None) -> np.ndarray:
    """Each viseme's share of the blend at every time, shape (n, 15): rows sum to 1. The blended shape is
    these weights times the visemes' shapes (what :func:`fit_shapes` fits). ``visemes``: default
    :data:`VISEMES`."""
    visemes = VISEMES if visemes is None else visemes
    by_number = {viseme.number: i for i, viseme in enumerate(visemes)}
    spoken = _spoken(phones, visemes)
    one_hot = np.zeros((len(spoken), len(visemes)))
    for i, (viseme, _) in enumerate(spoken):
        one_hot[i, by_number[viseme.number]] = 1.0
    return _blended(times_s, phones, spoken, one_hot)


def phone_weights(times_s: np.ndarray, phones: Sequence, *, visemes: Sequence[Viseme] | None = None) -> np.ndarray:
    """Each phone's share of the blend at every time, shape (n, len(:data:`PHONE_ORDER`)): rows sum to 1,
    by the dominance of each phone's viseme. The opening is these weights times the phones' own openings
    (what :func:`fit_shapes` fits for :data:`VISEMES`' ``phone_openings``)."""
    visemes = VISEMES if visemes is None else visemes
    spoken = _spoken(phones, visemes)
    one_hot = np.zeros((len(spoken), len(PHONE_ORDER)))
    for i, (viseme, label) in enumerate(spoken):
        one_hot[i, PHONE_ORDER.index(label if label in PHONE_ORDER else viseme.phones[0])] = 1.0
    return _blended(times_s, phones, spoken, one_hot)


@dataclass(frozen=True)
class MouthShape:
    """Mouth-shape tracks on a frame grid: opening (MNS), rounding (0..1), spread (fraction of width), and where
    the mouth comes from phones, ``viseme``: the number of the viseme said at each frame (0 between phones)."""

    opening: np.ndarray
    rounding: np.ndarray
    spread: np.ndarray
    viseme: np.ndarray | None = None


def shapes_from_phones(phones: Sequence, n_frames: int, *, fps: float,
                       visemes: Sequence[Viseme] | None = None) -> MouthShape:
    """The mouth shape at every frame of a grid, from timed phones (objects with ``label``, ``start_s``,
    ``end_s``), coarticulated by :func:`blend`, with the viseme said at each frame (:func:`said_visemes`). No
    phones: a neutral mouth. ``visemes``: the shapes (default :data:`VISEMES`, read when called)."""
    visemes = VISEMES if visemes is None else visemes
    if n_frames == 0 or len(phones) == 0:
        neutral = visemes[0]
        return MouthShape(np.full(n_frames, neutral.opening), np.full(n_frames, neutral.rounding),
                          np.full(n_frames, neutral.spread), np.zeros(n_frames, dtype=int))
    spoken = _spoken(phones, visemes)
    targets = np.array([[viseme.opening_of(label), viseme.rounding, viseme.spread] for viseme, label in spoken])
    shape = _blended(np.arange(n_frames) / fps, phones, spoken, targets)
    return MouthShape(shape[:, 0], shape[:, 1], shape[:, 2], said_visemes(phones, n_frames, fps=fps))


def said_visemes(phones: Sequence, n_frames: int, *, fps: float) -> np.ndarray:
    """The number of the viseme of the phone said at each frame of a grid (frame ``k`` at ``k / fps``), 0
    (neutral) where no phone covers it: what MPEG-4's FAP 1 (``viseme_select``) carries.

    Examples
    --------
    >>> from audio_features.phones import Phone
    >>> said_visemes([Phone("B", 0.1, 0.2), Phone("AA1", 0.2, 0.4)], 6, fps=10.0).tolist()
    [0, 1, 10, 10, 0, 0]
    """
    numbers = np.zeros(n_frames, dtype=int)
    starts = np.array([phone.start_s for phone in phones], float)
    ends = np.array([phone.end_s for phone in phones], float)
    if not n_frames or not starts.size:
        return numbers
    times = np.arange(n_frames) / fps
    order = np.argsort(starts, kind="stable")
    # the last phone started at or before each frame, if the frame is before its end
    index = np.searchsorted(starts[order], times + 1e-9, side="right") - 1
    inside = index >= 0
    chosen = order[np.clip(index, 0, None)]
    inside &= times < ends[chosen] - 1e-9
    labels = [viseme_of(phone.label).number for phone in phones]
    numbers[inside] = np.array(labels)[chosen[inside]]
    return numbers


def shape_faps(shape: MouthShape, *, gain: float = 1.0) -> dict[int, np.ndarray]:
    """Low-level lip FAPs of a mouth shape (see the module's geometry), scaled by ``gain``, and FAP 1 (the viseme
    said, :data:`VISEME_FAP`) where the shape has one and the lips move (``gain`` above 0).

    Examples
    --------
    >>> faps = shape_faps(MouthShape(np.array([200.0]), np.array([0.0]), np.array([0.0])))
    >>> float(faps[3][0] - faps[4][0] - faps[5][0])  # the inner-lip opening
    200.0
    """
    curves = _lip_geometry(shape.opening, shape.rounding, shape.spread, gain)
    # rounding noise of the blend (1e-20 where a shape is 0) is no motion
    out = {fap: np.where(np.abs(curves[fap]) < 1e-9, 0.0, curves[fap]) for fap in LIP_FAPS}
    if shape.viseme is not None and gain > 0:
        out[VISEME_FAP] = np.asarray(shape.viseme, float)
    return out


def shape_fap_values(opening: float, rounding: float, spread: float) -> dict[int, float]:
    """:func:`shape_faps` of one frame's shape, in plain floats (the same values, for a live frame).

    Examples
    --------
    >>> values = shape_fap_values(200.0, 0.0, 0.0)
    >>> values[3] - values[4] - values[5]
    200.0
    """
    curves = _lip_geometry(opening, rounding, spread, 1.0)
    return {fap: 0.0 if abs(curves[fap]) < 1e-9 else curves[fap] for fap in LIP_FAPS}


def _lip_geometry(opening, rounding, spread, gain: float) -> dict:
    """The lip FAPs of a shape, for arrays or floats alike (the same arithmetic either way)."""
    curves = {}
    for fap, share in OPENING_SHARES.items():
        curves[fap] = gain * share * opening
    curves[8] = curves[9] = MIDPOINT_FOLLOW * curves[4]
    curves[10] = curves[11] = MIDPOINT_FOLLOW * curves[5]
    curves[16] = curves[17] = gain * PROTRUSION_MNS * rounding
    curves[6] = curves[7] = gain * 512.0 * spread
    for inner, outer in OUTER_OF_INNER.items():
        if inner in curves:
            curves[outer] = curves[inner]
    return curves


def inner_opening(curves: dict[int, np.ndarray]) -> np.ndarray:
    """The inner-lip opening ``FAP 3 - FAP 4 - FAP 5`` (MNS) of lip curves."""
    return curves[3] - curves[4] - curves[5]


def fit_shapes(weights: Iterable[np.ndarray], targets: Iterable[np.ndarray], *, ridge: float = 1e-3,
               closed: Sequence[int] = (1,), nonnegative: bool = False,
               minimum: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
    """Least-squares viseme values from blend weights (rows summing to 1) and a target track per recording:
    ``targets ~ weights @ values``. Visemes in ``closed`` are held at 0 (the bilabial closure). With
    ``nonnegative``, values are kept >= 0 (openings); ``minimum`` (15 values) keeps each viseme's value at or
    above its own bound.

    Returns
    -------
    array of shape (15,)
    """
    from scipy.optimize import lsq_linear

    rows = np.vstack(list(weights))
    values = np.concatenate(list(targets))
    keep = np.isfinite(values)
    rows, values = rows[keep], values[keep]
    free = [j for j in range(rows.shape[1]) if j not in closed]
    design = np.vstack([rows[:, free], np.sqrt(ridge) * np.eye(len(free))])
    padded = np.concatenate([values, np.zeros(len(free))])
    lower = np.full(len(free), 0.0 if nonnegative else -np.inf)
    if minimum is not None:
        lower = np.maximum(lower, np.asarray(minimum, float)[free])
    solution = lsq_linear(design, padded, bounds=(lower, np.inf)).x
    out = np.zeros(rows.shape[1])
    out[free] = solution
    return out
