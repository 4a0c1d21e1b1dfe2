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

#: The public facade: ``from prosody import convert`` and so on, each imported when first asked for, so that
#: ``import prosody`` stays cheap.
_FACADE = {
    "convert": "prosody.jobs.pipeline",
    "compare": "prosody.evaluation.compare",
    "write_comparison": "prosody.evaluation.compare",
    "write_preview": "prosody.evaluation.preview",
    "LiveConverter": "prosody.jobs.stream",
    "read_fap": "prosody.fap.fapfile",
    "write_fap": "prosody.fap.fapfile",
    "write_stream": "prosody.fap.exporters",
    "FapStream": "prosody.fap.stream",
    "run_batch": "prosody.jobs.batch",
}
__all__ = ["__version__", *_FACADE]


def __getattr__(name: str):
    if name in _FACADE:
        from importlib import import_module

        value = getattr(import_module(_FACADE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'prosody' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
