"""The videos of a perceptual study (``prosody study stimuli``): one per stimulus and condition of a plan.

Each video is the 3D head (``prosody preview``'s, without the curve strip and without a caption, so nothing
on screen names the condition) animated by one condition, with the recording's audio: ``DIR/<stimulus>/
<condition>.mp4``, and beside it the same frames for the study page's WebGL head, ``<condition>.head.json``
(the FAP values the video shows). Paired trials show two of them side by side; the study page plays them
together, drawing the head itself from the frames (the video gives the sound and the clock) or, where WebGL is
off, showing the videos.

A condition is what :func:`prosody.convert` makes with some settings: the thesis's four (``none``, ``random``,
``speech``, ``truth``) are :data:`BUILT_IN`; a study's own are given in a conditions file (JSON), as
``convert``'s keyword arguments in plain values (``settings``) or as ``prosody convert``'s options (``options``,
read by ``prosody study stimuli``)::

    {"format": "visual-prosody-study-conditions", "version": 1,
     "conditions": {"calm": {"label": "Calm", "settings": {"expressivity": {"activation": 0.4},
                                                           "pad": "0.5,-0.3,0"}},
                    "arx":  {"options": "--model arx --brows thesis"}}}

In ``settings``, ``expressivity`` is an object of :class:`~prosody.motion.expressivity.Expressivity`'s fields
and ``eyebrow_rule`` one of :class:`~prosody.motion.eyebrows.AccentRule`'s (``{"rule": "accent", ...}``) or
:class:`~prosody.motion.eyebrows.EyebrowRule`'s (``{"rule": "thesis", ...}``); the rest are as ``convert`` takes
them. ``label`` is what the participant reads in an identification study (default: the name).

Recordings are found by the stimulus's name in a folder: ``<stimulus>.wav`` (or any audio ending the other
commands read), with ``<stimulus>.head.csv`` (or ``.fap``) for ``truth``. Every input is checked before the
first video is drawn. ``DIR/stimuli.json`` lists the videos with their SHA-256 and the settings that made them;
a video whose settings, audio and file are unchanged is not drawn again, and each is written atomically, so an
interrupted run goes on where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from audio_features import AUDIO_EXTENSIONS
from audio_features.atomic import atomic_write

from ..errors import ConfigError
from ..evaluation.preview import BROW_VIEW_SCALE, head_values, write_preview
from ..head.web import head_frames_document
from ..jobs.pipeline import convert
from ..motion.conditions import Condition
from .designs import StudyPlan

STIMULI_FORMAT = "visual-prosody-study-stimuli"
CONDITIONS_FORMAT = "visual-prosody-study-conditions"
FORMAT_VERSION = 1
MANIFEST = "stimuli.json"
#: The photo whose head the stimuli show (``study stimuli --face``), kept beside them for the ballot.
FACE_FILE = "face.png"
#: Largest conditions or manifest file read.
MAX_JSON_BYTES = 16 << 20
#: The thesis's four conditions: the settings (``convert``'s keyword arguments) that make each.
BUILT_IN: dict[str, dict[str, Any]] = {"NO_PROSODY": {"condition": "none"}, "RANDOM": {"condition": "random"},
                                       "SPEECH_DRIVEN": {"condition": "speech"},
                                       "GROUND_TRUTH": {"condition": "truth"}}
#: What a condition's settings may not hold: the recorded motion is found per stimulus.
PER_STIMULUS = ("ground_truth", "base", "features", "output_format", "progress")


@dataclass(frozen=True)
class StudyCondition:
    """One condition of a study: its name, the label participants read, its settings (the keyword arguments of
    :func:`prosody.jobs.pipeline.convert`, checked by :func:`condition_settings`) and, where it was given as
    ``prosody convert``'s options, those (``command_line``; the manifest records them)."""

    name: str
    label: str
    settings: Mapping[str, Any] = field(default_factory=dict)
    command_line: str = ""

    @property
    def needs_truth(self) -> bool:
        return Condition.parse(str(self.settings.get("condition", "speech"))) is Condition.GROUND_TRUTH

    @property
    def recipe(self) -> str:
        """What made it, as the manifest records it: its options, or its settings as JSON."""
        return self.command_line or json.dumps(self.settings, sort_keys=True, default=repr)


def condition_settings(name: str, given: Mapping[str, Any]) -> dict[str, Any]:
    """A condition's settings from plain values (a conditions file's ``settings``), checked by the library's
    rules as :func:`~prosody.jobs.pipeline.convert` would check them, before any video is drawn.

    Parameters
    ----------
    name : str
        The condition, for the messages.
    given : mapping
        ``convert``'s keyword arguments; ``expressivity`` and ``eyebrow_rule`` as objects of their fields.

    Returns
    -------
    dict
        The keyword arguments of ``convert``.

    Examples
    --------
    >>> condition_settings("calm", {"expressivity": {"activation": 0.4}})["expressivity"].activation
    0.4
    >>> condition_settings("calm", {"condition": "none", "model": "arx"})
    Traceback (most recent call last):
    ...
    prosody.errors.ConfigError: condition calm: model= is the head model of condition=speech; it is not used by \
condition=none
    """
    from ..motion.conditions import check_condition
    from ..motion.expressivity import Expressivity
    from ..motion.eyebrows import AccentRule, EyebrowRule
    from ..motion.settings import settings_groups

    settings = dict(given)
    try:
        if kept := [key for key in PER_STIMULUS if key in settings]:
            raise ConfigError(f"{', '.join(kept)} is found per stimulus (ground_truth: <stimulus>.head.csv next to "
                              "its recording); leave it out", parameter=tuple(kept))
        if isinstance(settings.get("expressivity"), Mapping):
            settings["expressivity"] = Expressivity(**settings["expressivity"])
        if isinstance(settings.get("eyebrow_rule"), Mapping):
            fields = dict(settings["eyebrow_rule"])
            rule = {"accent": AccentRule, "thesis": EyebrowRule}.get(fields.pop("rule", None))
            if rule is None:
                raise ConfigError("eyebrow_rule needs \"rule\": \"accent\" or \"thesis\"", parameter="eyebrow_rule")
            settings["eyebrow_rule"] = rule(**fields)
        condition = settings.pop("condition", "speech")
        groups = settings_groups("convert", settings)
        check_condition(condition, model=groups.motion.model, expressivity=groups.motion.expressivity)
    except TypeError as error:  # a keyword convert (or a rule) does not take
        raise ConfigError(f"condition {name}: {error}") from None
    except ConfigError as error:
        raise ConfigError(f"condition {name}: {error}", parameter=error.parameters) from None
    return {"condition": condition, **settings}


def study_conditions(plan: StudyPlan, path: str | os.PathLike[str] | None = None, *,
                     read_options: Callable[[str, str], dict[str, Any]] | None = None) -> dict[str, StudyCondition]:
    """A :class:`StudyCondition` for every condition of ``plan``: the thesis's four from :data:`BUILT_IN`, the
    others from the conditions file ``path``.

    Parameters
    ----------
    plan : StudyPlan
    path : path-like, optional
        The conditions file.
    read_options : callable (name, options) -> settings, optional
        Reads a condition given as command-line options (the ``prosody`` command gives its own); without it,
        such a condition is refused.

    Returns
    -------
    dict
        Name -> condition, in the plan's order.
    """
    given = read_conditions(path) if path is not None else {}
    conditions = {}
    for name in plan.conditions:
        if name not in given and name not in BUILT_IN:
            raise ConfigError(f"the plan's condition {name} is not one of the thesis's four: define it in a "
                              "conditions file (--conditions FILE.json)")
        label, entry = given.get(name, (name, {"settings": BUILT_IN.get(name, {})}))
        if "options" in entry:
            if read_options is None:
                raise ConfigError(f"condition {name} is given as command-line options: give its \"settings\" "
                                  "instead, or make the stimuli with 'prosody study stimuli'")
            conditions[name] = StudyCondition(name, label, read_options(name, entry["options"]), entry["options"])
        else:
            conditions[name] = StudyCondition(name, label, condition_settings(name, entry["settings"]))
    return conditions


def _read_json(path: str | os.PathLike[str], what: str) -> dict:
    from audio_features.inputs import open_input, reading

    try:
        with reading(path, ConfigError), open_input(path, text=True, encoding="utf-8",
                                                    max_bytes=MAX_JSON_BYTES) as handle:
            payload = json.load(handle)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as error:
        raise ConfigError(f"{path}: not a {what} (not JSON: {error})") from None
    if not isinstance(payload, dict):
        raise ConfigError(f"{path}: not a {what} (expected a JSON object)")
    return payload


def read_conditions(path: str | os.PathLike[str]) -> dict[str, tuple[str, dict[str, Any]]]:
    """A conditions file: ``{name: (label, entry)}`` in the file's order (names checked as plans check them),
    each entry holding its ``settings`` (an object) or its ``options`` (text)."""
    from .ballots import condition_name

    payload = _read_json(path, "study conditions file")
    if payload.get("format") != CONDITIONS_FORMAT or payload.get("version") != FORMAT_VERSION:
        raise ConfigError(f"{path}: not a study conditions file (expected \"format\": \"{CONDITIONS_FORMAT}\", "
                          f"\"version\": {FORMAT_VERSION})")
    entries = payload.get("conditions")
    if not isinstance(entries, dict) or not entries:
        raise ConfigError(f"{path}: \"conditions\" must be an object of one or more named conditions")
    found: dict[str, tuple[str, dict[str, Any]]] = {}
    for raw, entry in entries.items():
        try:
            name = condition_name(raw)
        except ConfigError as error:
            raise ConfigError(f"{path}: {error}") from None
        if (not isinstance(entry, dict) or set(entry) - {"label", "options", "settings"}
                or len(set(entry) & {"options", "settings"}) > 1):
            raise ConfigError(f"{path}: condition {raw!r} must be an object with \"settings\" or \"options\" (and "
                              "\"label\")")
        label = entry.get("label", name)
        if not isinstance(label, str) or not label.strip() or len(label) > 80:
            raise ConfigError(f"{path}: condition {raw!r}: \"label\" must be 1-80 characters")
        if "options" in entry:
            if not isinstance(entry["options"], str):
                raise ConfigError(f"{path}: condition {raw!r}: \"options\" must be text")
            found[name] = (label.strip(), {"options": entry["options"]})
        else:
            if not isinstance(entry.get("settings", {}), dict):
                raise ConfigError(f"{path}: condition {raw!r}: \"settings\" must be an object")
            found[name] = (label.strip(), {"settings": entry.get("settings", {})})
    return found


def find_recording(folder: Path, stimulus: str) -> Path | None:
    """``<stimulus>`` with an audio ending in ``folder`` (the first in AUDIO_EXTENSIONS order)."""
    for ending in AUDIO_EXTENSIONS:
        candidate = folder / f"{stimulus}{ending}"
        if candidate.is_file():
            return candidate
    return None


def find_truth(folder: Path, stimulus: str) -> Path | None:
    for ending in (".head.csv", ".fap"):
        candidate = folder / f"{stimulus}{ending}"
        if candidate.is_file():
            return candidate
    return None


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def read_manifest(folder: str | os.PathLike[str]) -> dict:
    """``DIR/stimuli.json``, checked to be this project's."""
    path = Path(folder) / MANIFEST
    if not path.is_file():
        raise ConfigError(f"{folder}: no {MANIFEST} here; make the stimuli first with 'prosody study stimuli PLAN "
                          f"--recordings DIR -o {folder}'")
    payload = _read_json(path, "stimuli manifest")
    if payload.get("format") != STIMULI_FORMAT or payload.get("version") != FORMAT_VERSION \
            or not isinstance(payload.get("videos"), dict) or not isinstance(payload.get("conditions"), dict):
        raise ConfigError(f"{path}: not a stimuli manifest of this project (format {STIMULI_FORMAT})")
    inside = Path(folder).resolve()
    for key, entry in payload["videos"].items():
        if not isinstance(entry, dict) or not isinstance(entry.get("file"), str) \
                or not re.fullmatch(r"[0-9a-f]{64}", str(entry.get("sha256", ""))):
            raise ConfigError(f"{path}: video {key!r} is not an object with a file name and its SHA-256; make the "
                              "stimuli again with 'prosody study stimuli'")
        if not (inside / entry["file"]).resolve().is_relative_to(inside):
            raise ConfigError(f"{path}: video {key!r} names {entry['file']!r}, outside {folder}: a manifest may "
                              "only name videos in its own folder")
    for name, entry in payload["conditions"].items():
        if not isinstance(entry, dict):
            raise ConfigError(f"{path}: condition {name!r} is not an object; make the stimuli again")
    return payload


def video_key(stimulus: str, condition: str) -> str:
    return f"{stimulus}/{condition}"


def make_stimuli(plan: StudyPlan, recordings: str | os.PathLike[str], output: str | os.PathLike[str],
                 conditions: Mapping[str, StudyCondition], *, width: int = 480, force: bool = False,
                 on_video: Callable[[str, str, bool], None] | None = None,
                 progress: Callable[[int, int], None] | None = None, face: Any = None) -> dict:
    """Draw every (stimulus, condition) video ``plan`` needs into ``output``; return the manifest written.

    Parameters
    ----------
    plan : StudyPlan
        The study's plan (:func:`prosody.study.designs.read_plan`).
    recordings : folder
        ``<stimulus>.wav`` for every stimulus, and ``<stimulus>.head.csv`` (or ``.fap``) where a condition is
        ``truth``.
    output : folder
        Where the videos and ``stimuli.json`` go (made if missing).
    conditions : mapping
        A :class:`StudyCondition` for every condition the plan names.
    width : int
        Video width in pixels (the face is square).
    force : bool
        Draw again videos that are already complete.
    on_video : callable, optional
        Called as ``on_video(stimulus, condition, drawn)`` after each video (``drawn`` False: kept as it was).
    progress : callable, optional
        ``progress(done, total)`` in videos.
    face : path of a photo, or PhotoHead, optional
        Every video shows the head of the person in this photo (:mod:`prosody.head.photo`; the frame keeps the
        photo's proportions); the photo is kept as ``OUT/face.png`` and the ballot's WebGL head is made from it.
    """
    folder, out = Path(recordings), Path(output)
    photo = _stimuli_photo(face)
    photo_digest = _image_sha256(photo.image) if photo is not None else None
    inputs = _stimulus_inputs(plan, folder, conditions)
    out.mkdir(parents=True, exist_ok=True)
    try:
        old = read_manifest(out)["videos"]
    except ConfigError:
        old = {}
    if photo is not None:  # kept beside the videos: the ballot's WebGL head is made from it
        from PIL import Image

        with atomic_write(out / FACE_FILE, mode="wb") as handle:
            Image.fromarray(photo.image).save(handle, format="PNG")
    manifest: dict[str, Any] = {"format": STIMULI_FORMAT, "version": FORMAT_VERSION, "plan_sha256": plan.sha256,
                "design": plan.design, "width": width,
                **({"face": {"file": FACE_FILE, "sha256": _sha256(out / FACE_FILE)}} if photo is not None else {}),
                "conditions": {name: {"label": conditions[name].label, "recipe": conditions[name].recipe}
                               for name in plan.conditions},
                "videos": {}}
    needed = sorted({(trial.stimulus, name) for trial in plan.trials for name in trial.conditions},
                    key=lambda pair: (plan.stimuli.index(pair[0]), plan.conditions.index(pair[1])))
    for done, (stimulus, name) in enumerate(needed, start=1):
        audio, truth = inputs[stimulus]
        condition = conditions[name]
        settings = json.dumps({"recipe": condition.recipe, "audio": _sha256(audio), "width": width,
                               **({"face": photo_digest} if photo_digest is not None else {}),
                               "truth": _sha256(truth) if truth is not None and condition.needs_truth else None},
                              sort_keys=True)
        key = video_key(stimulus, name)
        previous = old.get(key)
        kept = not force and _still_complete(previous, settings, out / stimulus, name)
        manifest["videos"][key] = previous if kept else _draw_video(
            audio, truth, condition, out, stimulus, name, width=width, photo=photo, settings=settings)
        _write_manifest(out, manifest, old, needed[done:])
        if on_video is not None:
            on_video(stimulus, name, not kept)
        if progress is not None:
            progress(done, len(needed))
    return manifest


def _stimuli_photo(face: Any) -> Any:
    """The photo head of ``face`` (read, and its face found, before any video is drawn), or None."""
    if face is None:
        return None
    from ..evaluation.preview import resolve_face

    photo = resolve_face(face)
    if isinstance(photo, str):
        raise ConfigError(f"the stimuli's face is a photo (JPEG or PNG), not {face!r}")
    return photo


def _stimulus_inputs(plan: StudyPlan, folder: Path, conditions: Mapping[str, StudyCondition],
                     ) -> dict[str, tuple[Path, Path | None]]:
    """Each stimulus's recording and (where a condition is ``truth``) its recorded motion; all problems at once."""
    missing = [name for name in plan.conditions if name not in conditions]
    if missing:
        raise ConfigError(f"the plan names condition(s) {', '.join(missing)} that are not defined: give them in a "
                          "conditions file (--conditions FILE.json)")
    if not folder.is_dir():
        raise ConfigError(f"{folder}: not a folder of recordings")
    truth_needed = any(conditions[name].needs_truth for name in plan.conditions)
    inputs: dict[str, tuple[Path, Path | None]] = {}
    problems = []
    for stimulus in plan.stimuli:
        audio = find_recording(folder, stimulus)
        truth = find_truth(folder, stimulus) if truth_needed else None
        if audio is None:
            problems.append(f"no recording {stimulus}.wav (or {', '.join(AUDIO_EXTENSIONS[1:4])}, ...)")
        elif truth_needed and truth is None:
            problems.append(f"no recorded motion {stimulus}.head.csv (or .fap) for the truth condition")
        else:
            inputs[stimulus] = (audio, truth)
    if problems:
        raise ConfigError(f"{folder}: " + "; ".join(problems[:10])
                          + (f"; and {len(problems) - 10} more" if len(problems) > 10 else ""))
    return inputs


def _still_complete(previous: Any, settings: str, folder: Path, name: str) -> bool:
    """Whether an earlier run's video and head frames were made with these settings and are unchanged."""
    path, motion = folder / f"{name}.mp4", folder / f"{name}.head.json"
    return (isinstance(previous, dict) and previous.get("settings") == settings and path.is_file()
            and previous.get("sha256") == _sha256(path) and motion.is_file()
            and previous.get("motion_sha256") == _sha256(motion))


def _draw_video(audio: Path, truth: Path | None, condition: StudyCondition, out: Path, stimulus: str, name: str,
                *, width: int, photo: Any, settings: str) -> dict[str, Any]:
    """Convert and draw one stimulus in one condition, with the head frames of the ballot's WebGL head; its
    manifest entry."""
    kwargs: dict[str, Any] = dict(condition.settings)
    if condition.needs_truth:
        kwargs["ground_truth"] = truth
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stream = convert(audio, **kwargs)
    for warning in caught:  # said once each, naming the video they are about
        warnings.warn(f"{video_key(stimulus, name)}: {warning.message}", warning.category, stacklevel=3)
    path = out / stimulus / f"{name}.mp4"
    motion = path.with_name(f"{name}.head.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_preview(stream, path, audio=audio, width=width, strip=False, captioned=False,
                  face=photo if photo is not None else "head")
    # the same frames for the page's WebGL head: the values the video shows (brows drawn as large)
    frames = head_frames_document(head_values(stream, brow_scale=BROW_VIEW_SCALE), fps=stream.fps)
    with atomic_write(motion, newline="\n") as handle:
        json.dump(frames, handle, separators=(",", ":"))
    return {"file": f"{stimulus}/{name}.mp4", "sha256": _sha256(path), "motion": f"{stimulus}/{name}.head.json",
            "motion_sha256": _sha256(motion), "seconds": round(stream.n_frames / stream.fps, 3), "settings": settings}


def _image_sha256(image: Any) -> str:
    return hashlib.sha256(image.tobytes() + str(image.shape).encode()).hexdigest()


def _write_manifest(out: Path, manifest: dict, old: dict, remaining: list[tuple[str, str]]) -> None:
    """The manifest after each video: what is done, and what an earlier run made that is still to check."""
    pending = {video_key(*pair) for pair in remaining}
    videos = {**{key: entry for key, entry in old.items() if key in pending}, **manifest["videos"]}
    with atomic_write(out / MANIFEST, newline="\n") as handle:
        json.dump({**manifest, "videos": videos}, handle, indent=1)
        handle.write("\n")


def check_stimuli(plan: StudyPlan, folder: str | os.PathLike[str]) -> dict:
    """The manifest of ``folder``, checked to hold every video of ``plan`` (made for this plan, file present)."""
    manifest = read_manifest(folder)
    if manifest.get("plan_sha256") != plan.sha256:
        raise ConfigError(f"{folder}: these stimuli were made for another plan; make them again with 'prosody study "
                          "stimuli'")
    needed = {video_key(trial.stimulus, name) for trial in plan.trials for name in trial.conditions}
    absent = sorted(key for key in needed if key not in manifest["videos"]
                    or not (Path(folder) / str(manifest["videos"][key].get("file", ""))).is_file())
    if absent:
        raise ConfigError(f"{folder}: {len(absent)} video(s) of the plan are missing ({', '.join(absent[:5])}"
                          f"{', ...' if len(absent) > 5 else ''}); run 'prosody study stimuli' again")
    return manifest

