"""The head models, in one room: what every one does (:class:`prosody.motion.heads.models.HeadModel`), the
three offline kinds (the prosodic generator, Zavala Chmelicka's ARX model, Jia et al.'s PAD gestures), the live
head, their settings, and their training. The shipped model files are in ``prosody/motion/models``."""
