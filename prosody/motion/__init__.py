"""The motion itself: the eyebrow rules, Perlin noise, the head models (the thesis's ARX and the default
prosodic generator) and their files, recorded motion, the four conditions, the audio controls and training."""
