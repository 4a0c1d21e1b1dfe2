"""Visual prosody from speech: head and eyebrow motion (MPEG-4 FAP streams) from audio.

The package is in layers, each importing only those before it:

- :mod:`prosody.errors`: the exceptions;
- :mod:`prosody.fap`: the FAP table, streams, the .fap reader and writer, the exporters;
- :mod:`prosody.measures`: how motion is measured against recorded motion;
- :mod:`prosody.motion`: the eyebrow rules, Perlin noise, the head models, recorded motion, the conditions,
  training;
- :mod:`prosody.evaluation`: comparisons, reports, plots, previews, perceptual studies;
- :mod:`prosody.jobs`: one recording (:func:`prosody.jobs.pipeline.convert`) and folders
  (:func:`prosody.jobs.batch.run_batch`);
- :mod:`prosody.cli`: the ``prosody`` command, a thin shell over them.
"""

from importlib import metadata as _metadata

try:
    __version__ = _metadata.version("visual-prosody")  # one source: pyproject.toml
except _metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree never installed
    __version__ = "0+unknown"
