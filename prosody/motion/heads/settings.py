"""The settings of the prosodic head models, declared once: each one's name, default and range.

:class:`HeadSettings` holds what the offline generator (:class:`prosody.motion.heads.prosodic.ProsodicHeadModel`)
and its live form (:class:`prosody.motion.heads.live.LiveHeadModel`) share; :class:`OfflineHeadSettings` and
:class:`LiveHeadSettings` extend it with their own and change the defaults cross-validation chose for each. The
models are these classes with a fit: their constructors, the ``settings`` of their files and the checks of
both come from the fields here.

Examples
--------
>>> OfflineHeadSettings().lookahead_s, LiveHeadSettings().lookahead_s
(0.5, 0.1)
>>> LiveHeadSettings(pitch_share=2.0).check_settings()
Traceback (most recent call last):
...
prosody.errors.ConfigError: pitch_share must be a number in [0, 1], got 2.0
"""

from __future__ import annotations

import dataclasses
from typing import Any

from ...validate import valid_number


def setting(default: float, low: float, high: float) -> Any:
    """A settings field: its default and its range (both ends included)."""
    return dataclasses.field(default=default, metadata={"range": (low, high)})


@dataclasses.dataclass(eq=False, repr=False, kw_only=True)
class HeadSettings:
    """Settings both prosodic heads share.

    Attributes
    ----------
    lookbehind_s, lookahead_s : float
        Audio read before and after each frame, in s.
    step_s : float
        Spacing of the offsets at which the smoothed features are read, in s.
    ridge : float
        Ridge penalty of the regressions, per standardised column.
    pitch_share : float
        How much of the head's pitch follows the predicted pitch (the rest is shaped noise).
    leak_s, pitch_leak_s : float
        Time constants of the noise's and the pitch's leaky integration, in s.
    idle_ratio : float
        Speed of the idle sway where no one speaks, against the speaking speed.
    envelope_power : float
        Sharpening of the predicted speed envelope.
    pitch_follow_s : float
        How quickly the pitch follows its prediction, in s (0: at once).
    """

    lookbehind_s: float = setting(0.5, 0.0, 5.0)
    lookahead_s: float = setting(0.5, 0.0, 5.0)
    step_s: float = setting(0.1, 1e-3, 5.0)
    ridge: float = setting(1e4, 0.0, 1e12)
    pitch_share: float = setting(0.95, 0.0, 1.0)
    leak_s: float = setting(2.0, 1e-2, 1e3)
    pitch_leak_s: float = setting(0.15, 1e-2, 1e3)
    idle_ratio: float = setting(0.15, 0.0, 1.0)
    envelope_power: float = setting(2.0, 1.0, 4.0)
    pitch_follow_s: float = setting(0.2, 0.0, 2.0)

    @classmethod
    def setting_names(cls) -> tuple[str, ...]:
        """The settings' names, in declaration order."""
        return tuple(field.name for field in dataclasses.fields(cls))

    @classmethod
    def setting_ranges(cls) -> dict[str, tuple[float, float]]:
        """Each setting's range (both ends included)."""
        return {field.name: field.metadata["range"] for field in dataclasses.fields(cls)}

    def settings(self) -> dict[str, float]:
        """The settings' values, by name."""
        return {name: getattr(self, name) for name in self.setting_names()}

    def check_settings(self) -> None:
        """Raise :class:`~prosody.errors.ConfigError` naming the first setting outside its range."""
        for name, (low, high) in self.setting_ranges().items():
            valid_number(getattr(self, name), name, low, high)


@dataclasses.dataclass(eq=False, repr=False, kw_only=True)
class OfflineHeadSettings(HeadSettings):
    """The offline generator's settings: the shared ones, the speed correction's iterations and the bursts.

    Attributes
    ----------
    speed_iterations : int
        Rounds of correcting the whole head's speed over the recording.
    burst_power : float
        How much the motion is sharpened into bursts and holds.
    """

    speed_iterations: int = setting(3, 0, 10)
    burst_power: float = setting(0.5, 0.0, 1.0)


@dataclasses.dataclass(eq=False, repr=False, kw_only=True)
class LiveHeadSettings(HeadSettings):
    """The live head's settings: a shorter look-ahead, the speech-presence window, and the defaults its own
    cross-validation chose.

    Attributes
    ----------
    presence_window_s : float
        Speech presence is the voiced share of this much audio up to the look-ahead, in s.
    """

    lookahead_s: float = setting(0.1, 0.0, 2.0)
    envelope_power: float = setting(3.0, 1.0, 4.0)
    pitch_follow_s: float = setting(0.1, 0.0, 2.0)
    presence_window_s: float = setting(0.25, 0.05, 10.0)
