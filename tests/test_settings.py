"""The settings groups (``prosody.motion.settings``): each setting declared once, taken as a group or as keywords
alike by ``convert``, ``compare`` and ``LiveConverter``."""

from __future__ import annotations

import dataclasses
import inspect
import re

import numpy as np
import pytest

from prosody import (
    AnalysisSettings,
    ChannelSettings,
    FaceSettings,
    LiveConverter,
    MotionSettings,
    compare,
    convert,
)
from prosody.errors import ConfigError
from prosody.fap.stream import FapStream
from prosody.jobs.batch import BatchOptions
from prosody.motion.expressivity import Expressivity
from prosody.motion.settings import LiveFields, SettingsFields, settings_groups

GROUPS = (AnalysisSettings, MotionSettings, FaceSettings, ChannelSettings)


@pytest.mark.parametrize(("target", "groups", "keywords"), [
    (convert, GROUPS, SettingsFields), (compare, GROUPS, SettingsFields),
    (LiveConverter, (AnalysisSettings, MotionSettings, ChannelSettings), LiveFields)])
def test_each_setting_is_a_typed_keyword_and_documented(target, groups, keywords):
    parameters = inspect.signature(target).parameters
    doc = inspect.getdoc(target) or ""
    fields_entry = doc[doc.index("\n**fields\n"):]
    for group in groups:
        assert parameters[group_name(group)].default == group()
        for field in dataclasses.fields(group):
            assert field.name in keywords.__optional_keys__, (target, field.name)
            assert f"``{field.name}``" in fields_entry, (target, field.name)


def group_name(group: type) -> str:
    return {AnalysisSettings: "analysis", MotionSettings: "motion", FaceSettings: "face",
            ChannelSettings: "channels"}[group]


def test_a_group_and_its_keywords_give_the_same_stream(speech):
    flat = convert(speech, fps=25, seed=4, lips=None, gains={"yaw": 0.5}, disabled=["roll"])
    grouped = convert(speech, analysis=AnalysisSettings(fps=25), motion=MotionSettings(seed=4),
                      face=FaceSettings(lips=None), channels=ChannelSettings(gains={"yaw": 0.5}, disabled=["roll"]))
    assert flat.fps == grouped.fps == 25 and flat.n_frames == grouped.n_frames == 43  # 1.7 s at 25 fps
    assert flat.active_faps == grouped.active_faps and 50 not in flat.active_faps
    np.testing.assert_array_equal(flat.values, grouped.values)
    other_seed = convert(speech, fps=25, seed=5, lips=None, gains={"yaw": 0.5}, disabled=["roll"])
    assert not np.array_equal(other_seed.values, flat.values)  # the seed reached the head


def test_a_keyword_overrides_its_groups_field_and_leaves_the_others(speech):
    stream = convert(speech, analysis=AnalysisSettings(fps=25, f0_ceiling_hz=400.0), fps=20, lips=None)
    assert stream.fps == 20 and stream.n_frames == 34


def test_the_live_converter_takes_them_both_ways():
    tone = 0.5 * np.sin(2 * np.pi * 150 * np.arange(16000) / 16000)
    flat = LiveConverter(16000, condition="random", fps=25, seed=2, disabled=["lips"])
    grouped = LiveConverter(16000, condition="random", analysis=AnalysisSettings(fps=25),
                            motion=MotionSettings(seed=2), channels=ChannelSettings(disabled=("lips",)))
    a, b = flat.push(tone) + flat.finish(), grouped.push(tone) + grouped.finish()
    assert flat.fps == grouped.fps == 25 and len(a) == len(b) == 25
    assert [frame.faps for frame in a] == [frame.faps for frame in b] and 3 not in a[0].faps
    other = LiveConverter(16000, condition="random", fps=25, seed=3, disabled=["lips"])
    assert [frame.faps for frame in other.push(tone) + other.finish()] != [frame.faps for frame in a]


def test_a_comparison_takes_them_both_ways(speech):
    flat = compare(speech, seed=1, seeds=1, lips=None, fps=25, conditions=["none"])
    grouped = compare(speech, seeds=1, motion=MotionSettings(seed=1), face=FaceSettings(lips=None),
                      analysis=AnalysisSettings(fps=25), conditions=["none"])
    assert flat.features.fps == grouped.features.fps == 25
    assert flat.metrics["conditions"].keys() == grouped.metrics["conditions"].keys() == {"NO_PROSODY"}


@pytest.mark.parametrize(("make", "message"), [
    (lambda: ChannelSettings(gains={"nose": 2.0}),
     "unknown channel(s) 'nose'; choose from pitch, yaw, roll, brows, lips"),
    (lambda: ChannelSettings(disabled=["ears"]), "unknown channel(s) 'ears'"),
    (lambda: ChannelSettings(gains={"yaw": float("nan")}), "gain of 'yaw' must be a number from 0 to 100"),
    # as the command line refuses them: a negative gain, one past 100, gains that are not a mapping
    (lambda: ChannelSettings(gains={"pitch": -1.0}), "0 stills it), got -1.0"),
    (lambda: ChannelSettings(gains={"lips": 1e6}), "gain of 'lips' must be a number from 0 to 100"),
    (lambda: ChannelSettings(gains=[("pitch", 2.0)]), "gains map channel names to numbers"),
    (lambda: FapStream.from_curves({3: np.zeros(3)}, fps=True), "fps must be a positive number, got True"),
    (lambda: FapStream.from_curves({3: np.zeros(3)}, fps="30"), "fps must be a positive number"),
    (lambda: ChannelSettings(gains={"yaw": True}), "0 stills it), got True"),
    (lambda: FaceSettings(lips="phonemes"), "unknown lip method 'phonemes'; choose visemes, acoustic, combined"),
    (lambda: MotionSettings(seed=-1), "seed"),
    (lambda: MotionSettings(expressivity={"spatial": 1.0}), "expressivity must be an Expressivity"),
])
def test_a_group_refuses_what_it_cannot_do(make, message):
    with pytest.raises(ConfigError) as caught:
        make()
    assert message in str(caught.value)


def test_a_group_of_another_kind_or_an_unknown_keyword_is_refused(speech):
    with pytest.raises(ConfigError, match="analysis must be a AnalysisSettings, got 25"):
        convert(speech, analysis=25)
    with pytest.raises(TypeError, match="colour"):
        convert(speech, colour="red")
    with pytest.raises(ConfigError, match="unknown channel"):  # checked before any analysis
        convert("no such file.wav", gains={"nose": 1.0})


def test_groups_are_frozen_and_compare_by_value():
    assert FaceSettings(lips="acoustic") == FaceSettings(lips="acoustic") != FaceSettings()
    with pytest.raises(dataclasses.FrozenInstanceError):
        FaceSettings().lips = "acoustic"  # type: ignore[misc]
    assert ChannelSettings(gains={"yaw": 2}).gain("yaw") == 2.0 and ChannelSettings().gain("lips") == 1.0
    assert ChannelSettings(gains={"yaw": np.float32(0.5)}).gain("yaw") == 0.5  # numpy numbers are numbers


def test_every_lip_method_is_accepted_by_a_batch():
    assert BatchOptions(lips="combined").lips == "combined"  # was refused while the command offered it
    with pytest.raises(ConfigError, match="unknown lip method"):
        BatchOptions(lips="phonemes")


def test_keywords_override_the_group_given_and_reach_only_their_own_group():
    groups = settings_groups("f", {"fps": 25.0, "lips": "acoustic", "disabled": ["roll"]},
                             analysis=AnalysisSettings(f0_floor_hz=60.0), face=FaceSettings(lips="combined"))
    assert groups.analysis == AnalysisSettings(fps=25.0, f0_floor_hz=60.0)  # the keyword over the object
    assert groups.face == FaceSettings(lips="acoustic") and groups.motion == MotionSettings()
    assert groups.channels.disabled_faps() == {50}
    with pytest.raises(TypeError, match=r"^f\(\) got an unexpected keyword argument 'lips'$"):
        settings_groups("f", {"lips": "acoustic"}, taking=("analysis", "motion", "channels"))


def test_the_signatures_show_the_groups_and_their_defaults():
    """What a reader and a type checker see in the source: each group a parameter with its defaults, and the
    fields as typed keywords (no signature rewritten at import)."""
    for function in (convert, compare, LiveConverter.__init__):
        parameters = inspect.signature(function).parameters
        assert parameters["analysis"].default == AnalysisSettings() and parameters["motion"].default == MotionSettings()
        assert parameters["fields"].kind is inspect.Parameter.VAR_KEYWORD
        assert not hasattr(function, "__wrapped__")


@pytest.mark.parametrize("keywords, said", [
    ({"condition": "none", "model": "arx"}, "model= is the head model of condition=speech"),
    ({"condition": "random", "ground_truth": "x.head.csv"}, "ground_truth= is the recorded motion of condition=truth"),
    ({"condition": "none", "expressivity": Expressivity(activation=0.5)}, "condition=none has none"),
    ({"lips": "acoustic", "transcript": "hello"}, "transcript= is read by the visemes"),
    ({"language": "es"}, "language= is the transcript's language"),
    ({"mouth_model": "m.json"}, "mouth_model= is the model of lips=acoustic"),
    ({"pad_map": "p.json"}, "pad_map= maps the state of pad="),
])
def test_python_gets_the_command_lines_refusals(speech, keywords, said) -> None:
    """convert(condition="none", model="arx") was accepted from Python and refused by the command line: the
    rules about which settings go together are the library's now (the command line says them with its flags),
    and they refuse before the audio is read."""
    with pytest.raises(ConfigError, match=re.escape(said)):
        convert(speech, None, **keywords)
