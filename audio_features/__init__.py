"""Acoustic features for visual prosody: Praat F0 with spline conditioning, and Praat intensity.

Everything is returned on a frame grid (frame ``k`` at ``k / fps`` seconds). This package never
imports :mod:`prosody`.
"""

from .audio import AUDIO_EXTENSIONS, Audio, load_audio
from .defaults import DEFAULT_F0_CEILING_HZ, DEFAULT_F0_FLOOR_HZ, DEFAULT_FPS
from .errors import (
    AnalysisError,
    AudioFeaturesError,
    AudioLoadError,
    NoVoicedFramesWarning,
    ParameterError,
    ParameterNote,
    VisualProsodyError,
)
from .features import (
    CSV_COLUMNS,
    Features,
    condition_f0,
    extract_features,
    read_features_csv,
)
from .tracks import F0Track, Track, frame_count

__all__ = [
    "AnalysisError",
    "AUDIO_EXTENSIONS",
    "CSV_COLUMNS",
    "DEFAULT_F0_CEILING_HZ",
    "DEFAULT_F0_FLOOR_HZ",
    "DEFAULT_FPS",
    "Audio",
    "AudioFeaturesError",
    "AudioLoadError",
    "F0Track",
    "Features",
    "NoVoicedFramesWarning",
    "ParameterError",
    "ParameterNote",
    "Track",
    "condition_f0",
    "extract_features",
    "frame_count",
    "load_audio",
    "read_features_csv",
    "VisualProsodyError",
]
