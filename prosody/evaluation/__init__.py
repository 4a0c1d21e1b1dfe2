"""Judging motion: comparing the conditions on a recording, reports, plots, the previews and the closed
loop of the 3D head. The perceptual studies have a room of their own, :mod:`prosody.study`."""
