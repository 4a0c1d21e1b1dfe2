"""Defaults shared by every function of both packages that takes these parameters: defined here only."""

#: Frame rate of the FAP grid, frames per second.
DEFAULT_FPS = 30.0
#: Pitch search range of Praat's autocorrelation pitch, Hz.
DEFAULT_F0_FLOOR_HZ = 75.0
DEFAULT_F0_CEILING_HZ = 500.0
#: Lowest pitch floor accepted, Hz: Praat's window is three periods of the floor (150 ms at 20 Hz, below any
#: voice's creak); a lower floor only makes the analysis slower and larger (0.01 Hz: a 300 s window).
MIN_F0_FLOOR_HZ = 20.0
