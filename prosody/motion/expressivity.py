"""Greta's six expressivity controls, applied to the motion of any head or brow generator.

The controls reshape a generator's output frame by frame and look at no future frame, so the offline
commands and the live stream apply the very same operation, and every generator (the prosodic head, Jia et al.'s
PAD gestures, the thesis's ARX model, Perlin noise, both brow rules, the live head and brows) gets the same
meaning for each control. Every control at its neutral value (activation 1, the others 0) leaves the motion
exactly as the generator made it.

Head (pitch, yaw and roll, about the rest pose). The head's own visible angular speed (its velocity through
two one-pole filters of 0.04 s, about 4 Hz), smoothed over 0.25 s and divided by its running average (20 s),
says how strongly it moves at each moment (``r``, 1 on average). The generator's frame-to-frame motion (its
velocity) is then scaled, filtered and integrated again, with a pull of 4 s back towards the generator's own
pose so that the two never drift apart. A gain that follows the speed would scale an axis's quick movements
(a nod's fall) more than its slow ones (the rise) and carry the pose away in one direction, so each axis's
rises and falls are rescaled to keep the generator's proportion (running means over 20 s):

- activation (OAC, 0..1): how often gestures happen. The head holds during its weakest moments, about
  ``1 - activation`` of the time: a threshold follows the running ``1 - activation`` quantile of ``r``, and a
  soft gate (``r^8 / (r^8 + threshold^8)``, smoothed over 0.1 s) lowers the velocity of the moments below it
  to a tenth (the idle sway), and the pull leads the held head towards the generator's running mean pose (20
  s, started as if the first pose had lasted 5 s) rather than its pose of the moment, so the generator's slow
  drifts do not pass either. 1 holds nothing, 0.5 the weaker half, 0 everything (``--still``): what is left is
  the idle sway and the slow walk of the mean pose, 0.16 of the head's spread on average over the
  talking-heads recordings (at most 0.22; three seeds each).
- spatial (SPC, -1..1): amplitude about the rest pose, times ``2^spatial`` (half at -1, double at +1).
- temporal (TMP, -1..1): the time a movement takes. Above 0 the velocity is smoothed by a one-pole filter of
  ``0.3 s * temporal``: each movement lasts longer and is slower, and still covers the same angle. Below 0 its
  quick part (above a 0.15 s one-pole) is boosted ``2 * |temporal|`` times: shorter, faster movements.
- fluidity (FLD, -1..1): smoothness. Above 0 the velocity goes through two one-pole filters of
  ``0.06 s * fluidity`` each (the jerk above about 2.5 Hz goes); below 0 its part above about 5 Hz (two
  one-poles of 0.03 s) is boosted ``2 * |fluidity|`` times: a jerkier head.
- power (PWR, -1..1): sharpness of accents. The velocity is multiplied by ``r^power`` below 0 and by
  ``r^(2 * power)`` above, divided by that gain's running average over the speed it scales (so the average speed
  stays), within 0.25..4: at +1 a moment twice as strong as average moves four times faster, so the strong
  moments grow and the weak ones shrink (bursts and holds); at -1 the speed is even, whatever the moment.
- repetition (REP, 0..1): on a strong accent (``r`` rising through 1.8, at most one every 1.5 s, none in the
  first second) the head nods again: two cycles of a 2.5 Hz nod on the pitch axis, their height
  ``repetition`` times the pitch's running spread. It only adds, as Greta's repetition adds strokes, so it
  has no negative side.

Brows (the inner and middle brows, FAP 31-34, ENS, 0 at rest). A raise is a stretch of frames above 0:

- activation: a share of the raises is kept, evenly spread (raise ``i`` is kept when
  ``floor((i + 1) * activation) > floor(i * activation)``): 1 keeps all, 0.5 every other one, 0 none.
- spatial: heights times ``2^spatial``.
- temporal: above 0 each raise holds its highest point ``0.5 s * temporal`` longer before it falls (over 0.1 s);
  below 0 a raise lasts at most ``1.2 s * 4^temporal`` (0.3 s at -1), then falls over 0.1 s.
- fluidity: above 0 the curve follows through two one-pole filters of ``0.08 s * fluidity`` (soft onsets and
  releases); below 0 it jumps towards the raise's highest point so far, by ``|fluidity|`` of the way (abrupt).
- power: the onset of each raise overshoots by ``power / 2`` of its height, decaying over 0.15 s (a flick
  at +1); below 0 the onset is held back by as much (a slow raise).
- repetition: 0.15 s after a raise at least as high as the average kept raise ends, a second, shorter raise
  (0.1 s up, 0.15 s held, 0.1 s down) of ``repetition * 0.7`` times its height.

Greta defines these six parameters for gestures (Hartmann, Mancini and Pelachaud, 2005); the numbers above
are this project's and are not Greta's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from ..errors import ConfigError

#: Ranges of the six controls and their neutral values.
RANGES = {"activation": (0.0, 1.0), "spatial": (-1.0, 1.0), "temporal": (-1.0, 1.0), "fluidity": (-1.0, 1.0),
          "power": (-1.0, 1.0), "repetition": (0.0, 1.0)}
NEUTRAL = {"activation": 1.0, "spatial": 0.0, "temporal": 0.0, "fluidity": 0.0, "power": 0.0, "repetition": 0.0}

# head
SPEED_SMOOTHING_S = 0.25
#: Time constant of the two one-poles that keep the visible part of the velocity (about 4 Hz).
VISIBLE_S = 0.04
REFERENCE_S = 20.0
IDLE_SHARE = 0.1
QUANTILE_STEP = 0.02
GATE_SHARPNESS = 8
GATE_SMOOTHING_S = 0.1
PULL_S = 4.0
#: The held pose (the generator's running mean) starts as if its first pose had lasted this long (s).
MEAN_START_S = 5.0
SLOW_S = 0.3
QUICK_S = 0.15
QUICK_BOOST = 2.0
FLUID_S = 0.06
JITTER_S = 0.03
JITTER_BOOST = 2.0
POWER_GAIN_RANGE = (0.25, 4.0)
POWER_SHARPENING = 2.0
#: Limits of the correction that balances each axis's rises against its falls.
BALANCE_RANGE = (0.5, 2.0)
ACCENT_RATIO = 1.8
ACCENT_REFRACTORY_S = 1.5
#: Accents count once the running average has this much motion behind it (s).
ACCENT_WARMUP_S = 1.0
NOD_HZ = 2.5
NOD_CYCLES = 2
# brows
BROW_HOLD_S = 0.5
BROW_LONGEST_S = 1.2
BROW_FALL_S = 0.1
BROW_FLUID_S = 0.08
BROW_FLICK_S = 0.15
ECHO_DELAY_S, ECHO_RISE_S, ECHO_HOLD_S, ECHO_SHARE = 0.15, 0.1, 0.15, 0.7
#: Below this a brow value counts as rest (ENS).
BROW_REST_ENS = 1e-6


@dataclass(frozen=True)
class Expressivity:
    """Greta's six expressivity parameters (see the module for what each one does).

    Parameters
    ----------
    activation : float in [0, 1]
        OAC, how often gestures happen (1, the default, as generated; 0 only an idle sway).
    spatial : float in [-1, 1]
        SPC, amplitude about rest (x ``2^spatial``).
    temporal : float in [-1, 1]
        TMP, duration and speed of movements (above 0 longer and slower).
    fluidity : float in [-1, 1]
        FLD, smoothness (above 0 smoother, below 0 jerkier).
    power : float in [-1, 1]
        PWR, sharpness of accents.
    repetition : float in [0, 1]
        REP, repeated nods (and brow raises) on strong accents.

    Examples
    --------
    >>> Expressivity().is_neutral
    True
    >>> Expressivity.still().activation
    0.0
    >>> Expressivity(spatial=2)
    Traceback (most recent call last):
    ...
    prosody.errors.ConfigError: spatial must be a number in [-1, 1], got 2
    """

    activation: float = 1.0
    spatial: float = 0.0
    temporal: float = 0.0
    fluidity: float = 0.0
    power: float = 0.0
    repetition: float = 0.0

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            low, high = RANGES[item.name]
            if isinstance(value, bool) or not (isinstance(value, (int, float)) and math.isfinite(value)
                                                and low <= value <= high):
                raise ConfigError(f"{item.name} must be a number in [{low:g}, {high:g}], got {value!r}")
            object.__setattr__(self, item.name, float(value))

    @classmethod
    def still(cls) -> Expressivity:
        """Activation 0: the head keeps only an idle sway and the brows stay at rest."""
        return cls(activation=0.0)

    @property
    def is_neutral(self) -> bool:
        return all(getattr(self, name) == value for name, value in NEUTRAL.items())

    def with_changes(self, **changes: float) -> Expressivity:
        """A copy with some controls changed (checked like the constructor)."""
        unknown = sorted(set(changes) - set(RANGES))
        if unknown:
            raise ConfigError(f"unknown expressivity control(s) {', '.join(unknown)}; choose from {', '.join(RANGES)}")
        return replace(self, **changes)

    def as_dict(self) -> dict[str, float]:
        return {name: getattr(self, name) for name in RANGES}


def _pole(time_constant_s: float, fps: float) -> float:
    """The feedback coefficient of a one-pole low-pass with this time constant (0: no smoothing)."""
    return math.exp(-1.0 / (time_constant_s * fps)) if time_constant_s > 0 else 0.0


class HeadShaper:
    """The expressivity controls on head motion, one frame at a time (AU, 3 axes, about the rest pose).

    ``step(frame)`` takes the generator's next frame and returns the shaped one; :func:`shape_head` runs it over
    a whole recording. The state is a few numbers per axis: a stream of any length runs in constant memory.
    """

    def __init__(self, expressivity: Expressivity, *, fps: float) -> None:
        if not (math.isfinite(fps) and fps > 0):
            raise ConfigError(f"fps must be a positive number, got {fps!r}")
        self.expressivity = expressivity
        self.fps = float(fps)
        # the state is a few floats per axis, kept as Python floats: a frame's arithmetic on three numbers runs
        # several times faster on them than on small arrays (18,000 frames of 10 minutes took 0.8 s, now 0.3 s)
        self._previous: list[float] | None = None
        self._output = [0.0, 0.0, 0.0]
        self._speed = 0.0
        self._reference = 0.0
        self._power_reference = 0.0
        self._instant_reference = 0.0
        self._frames = 0
        self._gate = 1.0
        self._slow = [0.0, 0.0, 0.0]
        self._mean = [0.0, 0.0, 0.0]  # the generator's running mean pose (20 s): where a held head rests
        self._fluid = ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        self._visible = ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        self._pitch_mean = 0.0
        self._pitch_power = 0.0
        self._last_accent = -math.inf
        self._nod_start: float | None = None
        self._nod_height = 0.0
        self._ratio = 0.0
        self._threshold = 1.0  # the held share's running quantile of the speed ratio
        # running means of each axis's rises and falls, as generated and as scaled by the gain
        self._distance = ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        self._shaped_distance = ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
        self.set(expressivity)

    def set(self, expressivity: Expressivity) -> None:
        """Change the controls from the next frame on (a live stream's controls can move while it runs)."""
        fps = self.fps
        self.expressivity = expressivity
        self._smooth_speed = _pole(SPEED_SMOOTHING_S, fps)
        self._visible_pole = _pole(VISIBLE_S, fps)
        self._smooth_gate = _pole(GATE_SMOOTHING_S, fps)
        self._pull = 1.0 - _pole(PULL_S, fps)
        tempo = expressivity.temporal
        self._tempo_pole = _pole(SLOW_S * tempo if tempo > 0 else QUICK_S, fps)
        fluid = expressivity.fluidity
        self._fluid_pole = _pole(FLUID_S * fluid if fluid > 0 else JITTER_S, fps)
        self._scale = 2.0 ** expressivity.spatial
        self._reshaping = bool(expressivity.activation < 1 or expressivity.power or expressivity.temporal
                               or expressivity.fluidity)

    def step(self, frame: np.ndarray) -> np.ndarray:
        """The shaped head pose (3 axes, AU) for the generator's pose ``frame``."""
        x = [float(value) for value in frame]
        if len(x) != 3:
            raise ConfigError(f"a head frame has 3 angles (pitch, yaw, roll), got {len(x)}")
        return np.array(self._run([x])[0])

    def _run(self, rows: list[list[float]]) -> list[list[float]]:
        """:meth:`step` over frames in order (each a new list of three floats, kept as the previous pose): the
        one implementation of the shaping, for a live stream's frame and for a whole recording. The running
        state is held in local variables through the loop (a frame costs a few microseconds)."""
        e = self.expressivity
        fps = self.fps
        activation, power, repetition = e.activation, e.power, e.repetition
        filtering = e.temporal != 0.0 or e.fluidity != 0.0
        visible_pole, smooth_speed, pull, scale = self._visible_pole, self._smooth_speed, self._pull, self._scale
        reshaping = self._reshaping
        low, high = BALANCE_RANGE
        gain_low, gain_high = POWER_GAIN_RANGE
        exponent = power if power < 0 else POWER_SHARPENING * power
        slowest_weight = 1.0 / (REFERENCE_S * fps)
        first, second = self._visible
        up, down = self._distance
        shaped_up, shaped_down = self._shaped_distance
        previous, output, mean = self._previous, self._output, self._mean
        speed, reference, frames = self._speed, self._reference, self._frames
        instant_reference, power_reference, last_ratio = self._instant_reference, self._power_reference, self._ratio
        out = []
        for x in rows:
            if previous is None:
                previous, output, mean = list(x), list(x), list(x)
                self._mean = mean
            velocity = [x[0] - previous[0], x[1] - previous[1], x[2] - previous[2]]
            previous = x
            frames += 1
            # how strongly the head moves now against its running average
            # the speed a viewer sees: the velocity below about 4 Hz (two one-poles), as the measures low-pass it
            for k in range(3):
                first[k] = visible_pole * first[k] + (1 - visible_pole) * velocity[k]
                second[k] = visible_pole * second[k] + (1 - visible_pole) * first[k]
            instant = math.sqrt(second[0] * second[0] + second[1] * second[1] + second[2] * second[2]) * fps
            speed = smooth_speed * speed + (1 - smooth_speed) * instant
            weight = max(1.0 / frames, slowest_weight)
            reference += weight * (speed - reference)
            mean_rate = 1.0 / min(frames + MEAN_START_S * fps, REFERENCE_S * fps)
            for k in range(3):
                mean[k] += (x[k] - mean[k]) * mean_rate
            ratio = speed / reference if reference > 0 else 1.0
            gain = 1.0
            target = x
            if activation < 1.0:
                gain, target = self._gated(ratio, x, mean, activation)
            if power != 0.0:
                # the gain's average over the speed it scales is kept at 1, so the average speed stays
                boost = ratio**exponent if ratio > 0 else 0.0
                instant_reference += weight * (instant - instant_reference)
                power_reference += weight * (boost * instant - power_reference)
                norm = power_reference / instant_reference if power_reference > 0 else 1.0
                gain *= min(max(boost / norm, gain_low), gain_high)
            if gain != 1.0:
                # each axis's rises and falls rescaled so that, on average, they stand in the proportion the
                # generator's do (their total kept as the gain makes it): a gain that follows the speed would
                # otherwise favour the direction in which the generator moves faster (a nod's quick fall) and
                # carry the pose away from the generator's, by more than the motion's spread within the pull's 4 s
                for k in range(3):
                    v = velocity[k]
                    rising, falling = (v, 0.0) if v > 0 else (0.0, v)
                    up[k] += weight * (rising - up[k])
                    down[k] += weight * (-falling - down[k])
                    shaped_up[k] += weight * (gain * rising - shaped_up[k])
                    shaped_down[k] += weight * (-gain * falling - shaped_down[k])
                    total = (shaped_up[k] + shaped_down[k]) / max(up[k] + down[k], 1e-300)
                    rise = (min(max(up[k] * total / shaped_up[k], low), high) if shaped_up[k] > 0
                            else min(max(1.0, low), high))
                    fall = (min(max(down[k] * total / shaped_down[k], low), high) if shaped_down[k] > 0
                            else min(max(1.0, low), high))
                    velocity[k] = gain * (rising * rise + falling * fall)
            if filtering:
                velocity = self._filtered(velocity, e)
            if reshaping:
                for k in range(3):
                    output[k] = output[k] + velocity[k]
                    output[k] += pull * (target[k] - output[k])
            else:
                output = list(x)
            shaped = [output[0] * scale, output[1] * scale, output[2] * scale]
            if repetition > 0:
                shaped[0] = (output[0] + self._nod(x[0], ratio, frames, last_ratio)) * scale
            last_ratio = ratio
            out.append(shaped)
        self._previous, self._output = previous, output
        self._speed, self._reference, self._frames = speed, reference, frames
        self._instant_reference, self._power_reference, self._ratio = instant_reference, power_reference, last_ratio
        return out

    def _gated(self, ratio: float, x: list[float], mean: list[float], activation: float,
               ) -> tuple[float, list[float]]:
        """The activation gate: the gain of the velocity and the pose the head is pulled to. The threshold
        follows the running (1 - activation) quantile of the ratio, so the share of time held is about
        1 - activation whatever the generator's own statistics."""
        below = 1.0 if ratio < self._threshold else 0.0
        self._threshold = max(0.0, self._threshold + QUANTILE_STEP * ((1.0 - activation) - below))
        open_ = 0.0 if activation <= 0 else ratio**GATE_SHARPNESS / (
            ratio**GATE_SHARPNESS + self._threshold**GATE_SHARPNESS + 1e-300)
        self._gate = self._smooth_gate * self._gate + (1 - self._smooth_gate) * open_
        # a held head is pulled towards its mean pose, not the generator's: the generator's slow drifts
        # would otherwise pass through the 4 s pull and keep a third of its spread
        return (IDLE_SHARE + (1 - IDLE_SHARE) * self._gate,
                [m + self._gate * (a - m) for a, m in zip(x, mean, strict=True)])

    def _filtered(self, velocity: list[float], e: Expressivity) -> list[float]:
        """The velocity slowed or quickened (temporal), then smoothed or jittered (fluidity)."""
        if e.temporal != 0.0:
            pole, slow = self._tempo_pole, self._slow
            for k in range(3):
                slow[k] = pole * slow[k] + (1 - pole) * velocity[k]
            velocity = (list(slow) if e.temporal > 0
                        else [v + QUICK_BOOST * -e.temporal * (v - w) for v, w in zip(velocity, slow, strict=True)])
        if e.fluidity != 0.0:
            pole = self._fluid_pole
            first, second = self._fluid
            for k in range(3):
                first[k] = pole * first[k] + (1 - pole) * velocity[k]
                second[k] = pole * second[k] + (1 - pole) * first[k]
            velocity = (list(second) if e.fluidity > 0
                        else [v + JITTER_BOOST * -e.fluidity * (v - w) for v, w in zip(velocity, second, strict=True)])
        return velocity

    def _nod(self, pitch: float, ratio: float, frames: int, last_ratio: float) -> float:
        """The repeated nod's part of the pitch axis at frame number ``frames`` (from 1; AU), the speed ratio
        ``ratio`` now and ``last_ratio`` a frame before."""
        fps = self.fps
        weight = max(1.0 / frames, 1.0 / (REFERENCE_S * fps))
        self._pitch_mean += weight * (pitch - self._pitch_mean)
        self._pitch_power += weight * ((pitch - self._pitch_mean) ** 2 - self._pitch_power)
        now = frames / fps
        if (last_ratio < ACCENT_RATIO <= ratio and now - self._last_accent >= ACCENT_REFRACTORY_S
                and frames > ACCENT_WARMUP_S * fps):
            self._last_accent = now
            self._nod_start = now
            self._nod_height = self.expressivity.repetition * math.sqrt(max(self._pitch_power, 0.0))
        if self._nod_start is None:
            return 0.0
        elapsed = now - self._nod_start
        length = NOD_CYCLES / NOD_HZ
        if elapsed > length:
            self._nod_start = None
            return 0.0
        # a downward nod first, in and out smoothly
        return -self._nod_height * math.sin(2 * math.pi * NOD_HZ * elapsed) * math.sin(math.pi * elapsed / length) ** 2


class BrowShaper:
    """The expressivity controls on the brows' raise curve (ENS, 0 at rest), one frame at a time."""

    def __init__(self, expressivity: Expressivity, *, fps: float) -> None:
        if not (math.isfinite(fps) and fps > 0):
            raise ConfigError(f"fps must be a positive number, got {fps!r}")
        self.fps = float(fps)
        self._frame = 0
        self._raising = False
        self._raises = 0
        self._kept = True
        self._onset = 0
        self._highest = 0.0  # the current raise's highest input so far
        self._held = 0.0  # the temporal hold: highest output of the raise, and frames since it was reached
        self._since_highest = 0
        self._smooth = [0.0, 0.0]
        self._kept_heights = 0.0
        self._kept_count = 0
        self._echo_at: int | None = None
        self._echo_height = 0.0
        self.set(expressivity)

    def set(self, expressivity: Expressivity) -> None:
        """Change the controls from the next frame on."""
        self.expressivity = expressivity
        self._fluid_pole = _pole(BROW_FLUID_S * max(expressivity.fluidity, 0.0), self.fps)

    def _frames_of(self, seconds: float) -> int:
        return max(1, int(round(seconds * self.fps)))

    def step(self, value: float) -> float:
        """The shaped brow height (ENS) for the generator's height ``value``."""
        e = self.expressivity
        if e.is_neutral:
            self._frame += 1
            return float(value)
        k = self._frame
        self._frame += 1
        value = float(value)
        self._follow_raise(value, k, e)
        out = value if (self._raising and self._kept) else 0.0
        if e.temporal != 0:
            out = self._timed(out, k, e.temporal)
        if e.power != 0 and self._raising and self._kept:
            out *= 1 + e.power / 2 * math.exp(-(k - self._onset) / (BROW_FLICK_S * self.fps))
        if e.fluidity > 0:
            pole = self._fluid_pole
            self._smooth[0] = pole * self._smooth[0] + (1 - pole) * out
            self._smooth[1] = pole * self._smooth[1] + (1 - pole) * self._smooth[0]
            out = self._smooth[1]
        elif e.fluidity < 0 and self._raising and self._kept and out > 0:
            out += -e.fluidity * (max(self._highest, out) - out)
        if self._echo_at is not None:
            out = self._echoed(out, k, e.repetition)
        return max(0.0, out) * 2.0**e.spatial

    def _follow_raise(self, value: float, k: int, e: Expressivity) -> None:
        """A raise's start (kept or left out by the activation) and end (an echo scheduled after a high one)."""
        if value > BROW_REST_ENS and not self._raising:
            self._raising, self._onset, self._highest = True, k, 0.0
            i = self._raises
            self._raises += 1
            self._kept = math.floor((i + 1) * e.activation + 1e-9) > math.floor(i * e.activation + 1e-9)
        elif value <= BROW_REST_ENS and self._raising:
            self._raising = False
            if self._kept:
                self._kept_heights += self._highest
                self._kept_count += 1
                if e.repetition > 0 and self._highest >= self._kept_heights / self._kept_count - 1e-9:
                    self._echo_at, self._echo_height = k + self._frames_of(ECHO_DELAY_S), self._highest
        if self._raising:
            self._highest = max(self._highest, value)

    def _timed(self, out: float, k: int, temporal: float) -> float:
        """Slower raises held at their height, then let fall (temporal > 0); quicker ones cut short (< 0)."""
        fall = self._frames_of(BROW_FALL_S)
        if temporal > 0:
            if out >= self._held:
                self._held, self._since_highest = out, 0
            else:
                self._since_highest += 1
                late = self._since_highest - self._frames_of(BROW_HOLD_S * temporal)
                held = self._held if late <= 0 else self._held * max(0.0, 1 - late / fall)
                if held <= 0:
                    self._held = 0.0
                out = max(out, held)
        elif self._raising:
            late = (k - self._onset) - self._frames_of(BROW_LONGEST_S * 4.0**temporal)
            if late > 0:
                out *= max(0.0, 1 - late / fall)
        return out

    def _echoed(self, out: float, k: int, repetition: float) -> float:
        """The echo of a high raise: a smaller raise after :data:`ECHO_DELAY_S` (repetition)."""
        assert self._echo_at is not None
        elapsed = k - self._echo_at
        rise, hold = self._frames_of(ECHO_RISE_S), self._frames_of(ECHO_HOLD_S)
        if elapsed >= 2 * rise + hold:
            self._echo_at = None
        elif elapsed >= 0:
            shape = min(1.0, (elapsed + 1) / rise, (2 * rise + hold - elapsed) / rise)
            out = max(out, repetition * ECHO_SHARE * self._echo_height * shape)
        return out


def shape_head(motion_au: np.ndarray, *, fps: float, expressivity: Expressivity) -> np.ndarray:
    """Head motion (n_frames, 3) in AU about the rest pose, shaped by the controls (the same numbers a live
    stream gets frame by frame). Neutral controls return the motion unchanged.

    Examples
    --------
    >>> t = np.arange(300) / 30
    >>> nod = np.column_stack([1000 * np.sin(2 * np.pi * t), 0 * t, 0 * t])
    >>> bigger = shape_head(nod, fps=30, expressivity=Expressivity(spatial=1))
    >>> round(float(bigger[:, 0].std() / nod[:, 0].std()), 3)
    2.0
    """
    motion = np.asarray(motion_au, float)
    if expressivity.is_neutral:
        return motion.copy()
    if motion.ndim != 2 or motion.shape[1] != 3:
        raise ConfigError(f"head motion has 3 angles a frame (pitch, yaw, roll), got shape {motion.shape}")
    shaper = HeadShaper(expressivity, fps=fps)
    return np.array(shaper._run(motion.tolist()), dtype=float).reshape(motion.shape)


def shape_brows(curve_ens: np.ndarray, *, fps: float, expressivity: Expressivity) -> np.ndarray:
    """A brow raise curve (n_frames,) in ENS shaped by the controls. Neutral controls return it unchanged.

    Examples
    --------
    >>> raises = np.zeros(90); raises[10:20] = 8.0; raises[40:50] = 8.0; raises[70:80] = 8.0
    >>> kept = shape_brows(raises, fps=30, expressivity=Expressivity(activation=0.5))
    >>> [float(kept[15]), float(kept[45]), float(kept[75])]
    [0.0, 8.0, 0.0]
    """
    curve = np.asarray(curve_ens, float)
    if expressivity.is_neutral:
        return curve.copy()
    shaper = BrowShaper(expressivity, fps=fps)
    return np.array([shaper.step(v) for v in curve])
