"""Functions that share a parameter share its default: every public function and method of both packages."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
from collections import defaultdict

import audio_features
import prosody
from prosody.motion.settings import AnalysisSettings, ChannelSettings, FaceSettings, MotionSettings

#: A parameter whose default is one of these groups takes its fields as keywords too.
SETTINGS_GROUPS = (AnalysisSettings, MotionSettings, FaceSettings, ChannelSettings)

#: Parameter names whose defaults rightly differ, and why.
DIFFERENT_MEANINGS = {
    "channels": "a PCM format's number of audio channels; elsewhere the motion channels' gains and switches",
    "face": "a conversion's face settings (lips, expressions); the head a preview draws (the 3D head or a photo)",
    "ridge": "the ARX penalty is per normalised coefficient, the prosodic one per standardised window column",
    "plots": "a comparison draws its figures unless told not to; a batch only when asked",
    "seeds": "settings are ranked on 3 seeds, then the chosen one is measured on 10",
    "source": "a description of where data came from, not a setting",
    "warnings": "a field of a result, not a setting",
    "name": "a stream's or file's label",
    "lookahead_s": "the offline head reads 0.5 s of the recording ahead; a live head only what a stream's delay "
                   "allows (0.1 s)",
    "envelope_power": "the offline head also sharpens its motion itself (burst_power), and cross-validation chose 2 "
                      "with it; the live head has no bursts and keeps the 3 chosen without them",
    "pitch_follow_s": "each head's cross-validation chose its own: the offline head's speed is relative to the "
                      "recording's average, the live head's to its training average, and the live head has no "
                      "bursts",
}


def shared_defaults() -> dict[str, dict[str, object]]:
    found: dict[str, dict[str, object]] = defaultdict(dict)
    for package in (audio_features, prosody):
        for info in pkgutil.walk_packages(package.__path__, prefix=package.__name__ + "."):
            if info.name == "prosody.__main__":
                continue
            module = importlib.import_module(info.name)
            for name, value in vars(module).items():
                if name.startswith("_") or getattr(value, "__module__", None) != module.__name__:
                    continue
                targets = [value]
                if inspect.isclass(value):
                    targets += [member for key, member in vars(value).items()
                                if inspect.isfunction(member) and not key.startswith("_")]
                for target in targets:
                    try:
                        signature = inspect.signature(target)
                    except (TypeError, ValueError):
                        continue
                    where = f"{module.__name__}.{target.__qualname__}"
                    for parameter in signature.parameters.values():
                        if parameter.default not in (inspect.Parameter.empty, None):
                            found[parameter.name][where] = parameter.default
                        if isinstance(parameter.default, SETTINGS_GROUPS):  # its fields are keywords too
                            for field in dataclasses.fields(parameter.default):
                                value = getattr(parameter.default, field.name)
                                if value is not None:
                                    found[field.name][where] = value
    return found


def test_functions_sharing_a_parameter_share_its_default() -> None:
    disagreements = []
    for parameter, where in shared_defaults().items():
        if parameter in DIFFERENT_MEANINGS or len(where) < 2:
            continue
        if len({repr(default) for default in where.values()}) > 1:
            disagreements.append(f"{parameter}: {where}")
    assert disagreements == []


def test_the_check_sees_the_shared_parameters() -> None:
    defaults = shared_defaults()
    # the analysis settings are taken by the feature extractor, convert, compare, batch and training alike
    assert len(defaults["fps"]) >= 5 and set(map(repr, defaults["fps"].values())) == {repr(audio_features.DEFAULT_FPS)}
    assert len(defaults["f0_floor_hz"]) >= 4
    assert {"prosody.jobs.pipeline.convert", "prosody.evaluation.compare.compare"} <= set(defaults["seed"])
