"""How the head is seen, shared by the CPU renderer and the browser's WebGL code: the camera and the lights.

The camera looks at the head from the front, :data:`CAMERA_DISTANCE_CM` away, at the height
:data:`LOOK_AT_Y_CM`, framing :data:`HALF_VIEW_CM` above and below that point at the head's distance (from the
top of the hair to the shoulders). Two directional lights (towards the lights, in camera axes: x right, y up,
z towards the viewer) and an ambient term light it, with a weak specular highlight.
"""

from __future__ import annotations

import numpy as np

CAMERA_DISTANCE_CM = 95.0
LOOK_AT_Y_CM = -2.5
HALF_VIEW_CM = 16.5
BACKGROUND = (0.925, 0.933, 0.949)

KEY_LIGHT = (-0.45, 0.55, 0.70)
FILL_LIGHT = (0.60, 0.05, 0.80)
KEY, FILL, AMBIENT, SPECULAR = 0.70, 0.28, 0.26, 0.10
#: The highlight's sharpness: cosine ** (2 ** SHININESS_DOUBLINGS).
SHININESS_DOUBLINGS = 5


def light_directions() -> np.ndarray:
    """The key and fill lights' unit directions, (2, 3)."""
    lights = np.array([KEY_LIGHT, FILL_LIGHT], float)
    return lights / np.linalg.norm(lights, axis=1, keepdims=True)
