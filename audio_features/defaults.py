"""Defaults shared by every function of both packages that takes these parameters: defined here only."""

#: Frame rate of the FAP grid, frames per second.
DEFAULT_FPS = 30.0
#: Pitch search range of Praat's autocorrelation pitch, Hz.
DEFAULT_F0_FLOOR_HZ = 75.0
DEFAULT_F0_CEILING_HZ = 500.0
