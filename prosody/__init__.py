"""Visual prosody from speech: head and eyebrow motion (MPEG-4 FAP streams) from audio.

Entry points: :func:`prosody.pipeline.convert` (one recording, one condition), :func:`prosody.compare.compare`
(the four conditions and their metrics), :func:`prosody.batch.run_batch` (folders), :mod:`prosody.study`
(paired-comparison studies). The ``prosody`` command is a thin shell over them (:mod:`prosody.cli`).
"""

from importlib import metadata as _metadata

try:
    __version__ = _metadata.version("visual-prosody")  # one source: pyproject.toml
except _metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree never installed
    __version__ = "0+unknown"
