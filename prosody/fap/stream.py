"""The FAP stream: per-frame values of the 68 MPEG-4 FAPs, with a per-frame mask."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError
from .table import BY_NUMBER, N_FAPS


def _fap_columns(faps: Iterable[int]) -> np.ndarray:
    columns = []
    for fap in faps:
        if fap not in BY_NUMBER:
            raise ConfigError(f"FAP {fap!r} does not exist: FAPs are numbered 1..{N_FAPS}")
        columns.append(fap - 1)
    return np.array(columns, dtype=int)


# arrays inside: equality is identity (numpy's == is elementwise), so it stays hashable
@dataclass(frozen=True, eq=False)
class FapStream:
    """Frames of MPEG-4 facial animation parameters.

    Parameters
    ----------
    values : float array of shape (n_frames, 68)
        Column ``j`` holds FAP ``j + 1`` in FAP units (AU = 1e-5 rad for rotations, 1/1024 of the
        reference distance for the rest). Values where the mask is off are ignored and kept at 0.
    mask : bool array of shape (n_frames, 68)
        True where the FAP is active in that frame (real files change their mask from frame to frame).
    fps : float > 0
        Frames per second; frame ``k`` is at ``k / fps`` seconds.
    name : str
        Stream name (written in the .fap header).
    """

    values: np.ndarray
    mask: np.ndarray
    fps: float
    name: str = "prosody"

    def __post_init__(self) -> None:
        # copies: the caller may go on changing the arrays it passed
        self._freeze(np.array(self.values, dtype=float), np.array(self.mask, dtype=bool))

    def _freeze(self, values: np.ndarray, mask: np.ndarray) -> None:
        """Check ``values`` and ``mask``, zero the values where masked off (in place) and make both the
        stream's own, read-only arrays."""
        if values.ndim != 2 or values.shape[1] != N_FAPS:
            raise ConfigError(f"FAP values must have shape (n_frames, {N_FAPS}), got {values.shape!r}")
        if mask.shape != values.shape:
            raise ConfigError(f"FAP mask shape {mask.shape!r} differs from the values' {values.shape!r}")
        if isinstance(self.fps, (bool, np.bool_)) or not isinstance(self.fps, (int, float, np.integer, np.floating)) \
                or not (np.isfinite(self.fps) and self.fps > 0):
            raise ConfigError(f"fps must be a positive number, got {self.fps!r}")
        if not isinstance(self.name, str):
            raise ConfigError(f"a stream's name is text, got {type(self.name).__name__}")
        object.__setattr__(self, "fps", float(self.fps))
        if not np.all(np.isfinite(values) | ~mask):
            raise ConfigError("active FAP values must be finite")
        if values.flags.writeable:  # read-only arrays are another stream's, zeroed already
            np.copyto(values, 0.0, where=~mask)
        values.flags.writeable = False
        mask.flags.writeable = False
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "mask", mask)

    @classmethod
    def _adopt(cls, values: np.ndarray, mask: np.ndarray, fps: float, name: str) -> FapStream:
        """A stream that takes over arrays made for it (float64 values, bool mask), without copying them:
        long streams (216 000 frames x 68 FAPs for 2 hours) are 117 MB a copy."""
        stream = object.__new__(cls)
        object.__setattr__(stream, "fps", fps)
        object.__setattr__(stream, "name", name)
        stream._freeze(values, mask)
        return stream

    # construction -------------------------------------------------------------------------------------
    @classmethod
    def empty(cls, n_frames: int, *, fps: float, name: str = "prosody") -> FapStream:
        """A stream of ``n_frames`` frames with every FAP masked off."""
        return cls._adopt(np.zeros((n_frames, N_FAPS)), np.zeros((n_frames, N_FAPS), bool), fps, name)

    @classmethod
    def from_curves(cls, curves: Mapping[int, np.ndarray], *, fps: float, name: str = "prosody",
                    n_frames: int | None = None) -> FapStream:
        """A stream whose given FAPs are active in every frame, with the given values (FAP units).

        Examples
        --------
        >>> import numpy as np
        >>> stream = FapStream.from_curves({48: np.array([0.0, 100.0])}, fps=30)
        >>> stream.active_faps, stream.curve(48).tolist()
        ((48,), [0.0, 100.0])
        """
        lengths = {np.shape(curve)[0] for curve in curves.values()}
        if n_frames is not None:
            lengths.add(n_frames)
        if len(lengths) > 1:
            raise ConfigError(f"curves have different lengths {sorted(lengths)!r}")
        n = lengths.pop() if lengths else 0
        return cls._set_curves(np.zeros((n, N_FAPS)), np.zeros((n, N_FAPS), bool), curves, fps=fps, name=name)

    # access -------------------------------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return int(self.values.shape[0])

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    @property
    def times_s(self) -> np.ndarray:
        return np.arange(self.n_frames) / self.fps

    @property
    def active_faps(self) -> tuple[int, ...]:
        """FAP numbers whose mask bit is set in at least one frame, ascending."""
        return tuple(int(j) + 1 for j in np.flatnonzero(self.mask.any(axis=0)))

    def curve(self, fap: int) -> np.ndarray:
        """Values of one FAP over all frames.

        Parameters
        ----------
        fap : int
            FAP number, 1 to 68.

        Returns
        -------
        numpy.ndarray
            Shape (n_frames,), in FAP units, 0 where masked off (a copy).
        """
        return self.values[:, _fap_columns([fap])[0]].copy()

    def curves(self, faps: Iterable[int]) -> np.ndarray:
        """Values of several FAPs.

        Parameters
        ----------
        faps : iterable of int
            FAP numbers, 1 to 68, in the order wanted.

        Returns
        -------
        numpy.ndarray
            Shape (n_frames, len(faps)), in FAP units, 0 where masked off (a copy).
        """
        return self.values[:, _fap_columns(faps)].copy()

    # transformations ----------------------------------------------------------------------------------
    def with_curves(self, curves: Mapping[int, np.ndarray]) -> FapStream:
        """A copy in which the given FAPs are set (and active) in every frame.

        Parameters
        ----------
        curves : mapping of int to array
            FAP number -> values in FAP units, one per frame.

        Returns
        -------
        FapStream
        """
        return self._set_curves(self.values.copy(), self.mask.copy(), curves, fps=self.fps, name=self.name)

    @classmethod
    def _set_curves(cls, values: np.ndarray, mask: np.ndarray, curves: Mapping[int, np.ndarray], *, fps: float,
                    name: str) -> FapStream:
        n_frames = values.shape[0]
        for fap, curve in curves.items():
            column = _fap_columns([fap])[0]
            curve = np.asarray(curve, dtype=float)
            if curve.shape != (n_frames,):
                raise ConfigError(f"FAP {fap} curve has shape {curve.shape!r}, expected ({n_frames},)")
            values[:, column] = curve
            mask[:, column] = True
        return cls._adopt(values, mask, fps, name)

    def select(self, faps: Iterable[int]) -> FapStream:
        """A copy in which only the given FAPs keep their mask; every other FAP is masked off.

        Parameters
        ----------
        faps : iterable of int
            The FAPs kept.

        Returns
        -------
        FapStream
        """
        keep = np.zeros(N_FAPS, bool)
        keep[_fap_columns(faps)] = True
        return self._masked_off(np.flatnonzero(~keep))

    def without(self, faps: Iterable[int]) -> FapStream:
        """A copy with the given FAPs masked off.

        Parameters
        ----------
        faps : iterable of int
            The FAPs left out.

        Returns
        -------
        FapStream
            This stream itself when none of them is active.
        """
        return self._masked_off(_fap_columns(faps))

    def _masked_off(self, columns: np.ndarray) -> FapStream:
        columns = columns[self.mask[:, columns].any(axis=0)]
        if columns.size == 0:
            return self
        mask = self.mask.copy()
        mask[:, columns] = False
        values = self.values
        if np.any(values[:, columns]):  # copy only when the dropped FAPs have values to zero
            values = values.copy()
            values[:, columns] = 0.0
        return FapStream._adopt(values, mask, self.fps, self.name)

    def scaled(self, gains: Mapping[int, float], *, about: Mapping[int, float] | None = None) -> FapStream:
        """A copy with the given FAPs' motion multiplied by their gain (the intensity controls).

        Parameters
        ----------
        gains : mapping of int to float
            FAP number -> finite gain; 0 keeps the FAP, still at its rest value.
        about : mapping of int to float, optional
            FAP number -> the rest value the motion is scaled about (0 when not given).

        Returns
        -------
        FapStream
            This stream itself when every gain is 1.
        """
        about = dict(about or {})
        for fap, gain in gains.items():
            if not np.isfinite(gain):
                raise ConfigError(f"gain of FAP {fap} must be a finite number, got {gain!r}")
        changing = {fap: gain for fap, gain in gains.items() if gain != 1}
        if not changing:
            return self
        values = self.values.copy()
        for fap, gain in changing.items():
            rest = float(about.get(fap, 0.0))
            column = _fap_columns([fap])[0]
            values[:, column] = rest + (values[:, column] - rest) * gain
        return FapStream._adopt(values, self.mask, self.fps, self.name)

    def renamed(self, name: str) -> FapStream:
        """The same frames under another name.

        Parameters
        ----------
        name : str
            The new name (the .fap header's).

        Returns
        -------
        FapStream
        """
        return FapStream._adopt(self.values, self.mask, self.fps, name)

    def resampled(self, fps: float, *, n_frames: int | None = None) -> FapStream:
        """The stream on another frame grid: values linearly interpolated (those of the high-level FAPs 1 and 2,
        which number a viseme or an expression, from the nearest frame), masks from the nearest frame.

        Parameters
        ----------
        fps : float
            The new frame rate.
        n_frames : int, optional
            Frames of the result (default: the same duration); frames past the end of this stream hold its
            last frame.

        Returns
        -------
        FapStream
        """
        if n_frames is None:
            n_frames = int(round(self.duration_s * fps))
        if self.n_frames == 0:
            return FapStream.empty(n_frames, fps=fps, name=self.name)
        position = np.arange(n_frames) * self.fps / fps
        nearest = np.clip(np.rint(position).astype(int), 0, self.n_frames - 1)
        values = np.empty((n_frames, N_FAPS))
        source = np.arange(self.n_frames)
        for column in range(N_FAPS):
            values[:, column] = np.interp(position, source, self.values[:, column])
        values[:, :2] = self.values[nearest, :2]
        return FapStream(values, self.mask[nearest], fps, self.name)

    def merged_over(self, base: FapStream) -> FapStream:
        """Carry ``base``'s FAPs (lips, eyes, ...) under this stream's active FAPs.

        Parameters
        ----------
        base : FapStream
            The stream underneath; resampled onto this grid when its rate differs, and masked off past its
            own end.

        Returns
        -------
        FapStream
            This stream's length and rate; where this stream has a FAP active, its value wins.
        """
        if base.fps != self.fps:
            base = base.resampled(self.fps)
        n = min(base.n_frames, self.n_frames)
        values = np.zeros_like(self.values)
        mask = np.zeros_like(self.mask)
        values[:n] = base.values[:n]
        mask[:n] = base.mask[:n]
        ours = self.mask
        values[ours] = self.values[ours]
        mask |= ours
        return FapStream(values, mask, self.fps, self.name)

    def to_physical(self) -> np.ndarray:
        """Values in physical units.

        Returns
        -------
        numpy.ndarray
            Shape (n_frames, 68): radians for AU FAPs, fractions of the reference distance (ENS0, MNS0, ...)
            for the rest; NaN where masked off.
        """
        scale = np.array([BY_NUMBER[j + 1].to_physical(1.0) for j in range(N_FAPS)])
        physical = self.values * scale
        physical[~self.mask] = np.nan
        return physical
