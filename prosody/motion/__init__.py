"""The motion itself, in rooms. Shared by all: the eyebrow rules, Perlin noise, the expressivity controls,
the audio controls and the model files. :mod:`prosody.motion.face`: the lips, expressions and
emotional states. :mod:`prosody.motion.heads`: the head models and their training. On top, joining them: the
settings groups (:mod:`prosody.motion.settings`) and the four conditions (:mod:`prosody.motion.conditions`)."""
