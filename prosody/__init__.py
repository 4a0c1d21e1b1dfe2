"""Visual prosody from speech: head and eyebrow motion (MPEG-4 FAP streams) from audio.

The package is in layers, each importing only those before it:

- :mod:`prosody.errors`: the exceptions; :mod:`prosody.validate`: the checks of callers' values;
- :mod:`prosody.net`: what the live and study servers share (addresses, the origins they answer, headers);
- :mod:`prosody.fap`: the FAP table and units, streams, the .fap reader and writer, the exporters, recorded
  motion's files;
- :mod:`prosody.head`: the 3D head (mesh, rig, renderer, glTF, WebGL model);
- :mod:`prosody.outputs`: every output format by name and ending, and the writer that chooses among them;
- :mod:`prosody.measures`: how motion is measured against recorded motion;
- :mod:`prosody.motion`: the eyebrow rules, Perlin noise and the expressivity controls; its
  rooms :mod:`prosody.motion.face` (lips, expressions, PAD states) and :mod:`prosody.motion.heads` (the head
  models behind one protocol, offline and live, and their training); then the settings groups and the
  conditions that join them;
- :mod:`prosody.tracking`: videos made into recorded motion;
- :mod:`prosody.evaluation`: comparisons, reports, plots, previews, the head's closed loop;
- :mod:`prosody.jobs`: one recording (:func:`prosody.jobs.pipeline.convert`), folders
  (:func:`prosody.jobs.batch.run_batch`) and videos tracked;
- :mod:`prosody.live`: live conversion and whole live sessions (:class:`prosody.live.session.StreamSession`);
- :mod:`prosody.study`: perceptual studies from plan to analysis;
- :mod:`prosody.cli`: the ``prosody`` command, one module per command.
"""



def _version() -> str:
    """The installed release (one source: pyproject.toml); read when first asked for, since reading a
    distribution's metadata costs a command about 35 ms of start-up."""
    from importlib import metadata

    try:
        return metadata.version("visual-prosody")
    except metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree never installed
        return "0+unknown"


#: The public facade: ``from prosody import convert`` and so on, each imported when first asked for, so that
#: ``import prosody`` stays cheap.
_FACADE = {
    "convert": "prosody.jobs.pipeline",
    "compare": "prosody.evaluation.compare",
    "write_comparison": "prosody.evaluation.compare",
    "write_preview": "prosody.evaluation.preview",
    "LiveConverter": "prosody.live.converter",
    "StreamSession": "prosody.live.session",
    "read_fap": "prosody.fap.fapfile",
    "write_fap": "prosody.fap.fapfile",
    "write_stream": "prosody.outputs",
    "FapStream": "prosody.fap.stream",
    "run_batch": "prosody.jobs.batch",
    "AnalysisSettings": "prosody.motion.settings",
    "MotionSettings": "prosody.motion.settings",
    "FaceSettings": "prosody.motion.settings",
    "ChannelSettings": "prosody.motion.settings",
}
__all__ = ["__version__", *_FACADE]


def __getattr__(name: str):
    if name == "__version__":
        globals()["__version__"] = version = _version()
        return version
    if name in _FACADE:
        from importlib import import_module

        value = getattr(import_module(_FACADE[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'prosody' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
