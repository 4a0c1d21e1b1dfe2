"""Types of the lazy facade of :mod:`prosody`: each name is imported when first asked for, and a type checker
reads it from its own module, whose source carries its signature."""

from prosody.evaluation.compare import compare as compare
from prosody.evaluation.compare import write_comparison as write_comparison
from prosody.evaluation.preview import write_preview as write_preview
from prosody.fap.fapfile import read_fap as read_fap
from prosody.fap.fapfile import write_fap as write_fap
from prosody.fap.stream import FapStream as FapStream
from prosody.jobs.batch import run_batch as run_batch
from prosody.jobs.pipeline import convert as convert
from prosody.live.converter import LiveConverter as LiveConverter
from prosody.live.session import StreamSession as StreamSession
from prosody.motion.settings import AnalysisSettings as AnalysisSettings
from prosody.motion.settings import ChannelSettings as ChannelSettings
from prosody.motion.settings import FaceSettings as FaceSettings
from prosody.motion.settings import MotionSettings as MotionSettings
from prosody.outputs import write_stream as write_stream

__version__: str
__all__: list[str]
