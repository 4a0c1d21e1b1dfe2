"""The measures of a comparison as types: what ``metrics.json`` holds, read once and checked against its version.

:func:`prosody.evaluation.compare.compare` writes its measures as JSON (``Comparison.metrics``, and
``metrics.json``); :meth:`Metrics.from_json` reads such a document into these classes, refusing one of another
layout version, so that readers (the batch summary, the reports) use attributes that always exist (None where a
measure is undefined) instead of walking nested dictionaries. :meth:`Metrics.to_json` gives the document back.

Examples
--------
>>> head = HeadMeasures.from_json({"speed_envelope_r": 0.3, "std_ratio": {"48": 1.1}})
>>> head.speed_envelope_r, head.pitch_r, head.std_ratio["48"], head.std_ratio["50"]
(0.3, None, 1.1, None)
>>> Metrics.from_json({"version": 1})
Traceback (most recent call last):
...
prosody.errors.ConfigError: metrics of layout version 1: this version of prosody reads version 2 (compare again)
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

from ..errors import ConfigError
from ..measures import BROW_MEASURES, HEAD_MEASURES, MOUTH_MEASURES

#: Version of the metrics.json layout (2: head measures per condition, controls, seeds).
METRICS_VERSION = 2

Value = float | None


def _values(block: Mapping[str, Any] | None, keys: tuple[str, ...]) -> dict[str, Value]:
    block = block or {}
    return {key: block.get(key) for key in keys}


@dataclasses.dataclass(frozen=True)
class Agreement:
    """Events matched against recorded ones (brow onsets, lip closures): precision, recall and F1."""

    precision: Value = None
    recall: Value = None
    f1: Value = None

    @classmethod
    def from_json(cls, block: Mapping[str, Any] | None) -> Agreement:
        return cls(**_values(block, ("precision", "recall", "f1")))

    def to_json(self) -> dict[str, Value]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True)
class _Measures:
    """A block of single measures (named by ``KEYS``) and its one nested group."""

    KEYS: ClassVar[tuple[str, ...]] = ()
    GROUP: ClassVar[str] = ""

    values: dict[str, Value] = dataclasses.field(default_factory=dict)

    def __getattr__(self, name: str) -> Value:
        if name in type(self).KEYS:
            return self.values.get(name)
        raise AttributeError(f"{type(self).__name__} has no measure {name!r}")

    def to_json(self) -> dict[str, Any]:
        return {**{key: self.values.get(key) for key in self.KEYS}, self.GROUP: self._group_json()}

    def _group_json(self) -> Any:  # pragma: no cover - every block defines its group
        raise NotImplementedError


@dataclasses.dataclass(frozen=True)
class HeadMeasures(_Measures):
    """The head against recorded motion (:func:`prosody.measures.head_metrics`); ``std_ratio`` per axis."""

    KEYS: ClassVar[tuple[str, ...]] = HEAD_MEASURES
    GROUP: ClassVar[str] = "std_ratio"
    std_ratio: dict[str, Value] = dataclasses.field(default_factory=lambda: dict.fromkeys(("48", "49", "50")))

    @classmethod
    def from_json(cls, block: Mapping[str, Any] | None) -> HeadMeasures:
        ratios = (block or {}).get("std_ratio") or {}
        return cls(_values(block, HEAD_MEASURES), {axis: ratios.get(axis) for axis in ("48", "49", "50")})

    def _group_json(self) -> dict[str, Value]:
        return dict(self.std_ratio)


@dataclasses.dataclass(frozen=True)
class BrowMeasures(_Measures):
    """The brows against recorded ones (:func:`prosody.measures.brow_metrics`); ``onsets`` as an agreement."""

    KEYS: ClassVar[tuple[str, ...]] = BROW_MEASURES
    GROUP: ClassVar[str] = "onsets"
    onsets: Agreement = Agreement()

    @classmethod
    def from_json(cls, block: Mapping[str, Any] | None) -> BrowMeasures:
        return cls(_values(block, BROW_MEASURES), Agreement.from_json((block or {}).get("onsets")))

    def _group_json(self) -> dict[str, Value]:
        return self.onsets.to_json()


@dataclasses.dataclass(frozen=True)
class MouthMeasures(_Measures):
    """The lips against a tracked mouth (:func:`prosody.measures.mouth_metrics`); ``closures`` as an agreement."""

    KEYS: ClassVar[tuple[str, ...]] = MOUTH_MEASURES
    GROUP: ClassVar[str] = "closures"
    closures: Agreement = Agreement()

    @classmethod
    def from_json(cls, block: Mapping[str, Any] | None) -> MouthMeasures:
        return cls(_values(block, MOUTH_MEASURES), Agreement.from_json((block or {}).get("closures")))

    def _group_json(self) -> dict[str, Value]:
        return self.closures.to_json()


@dataclasses.dataclass(frozen=True)
class ConditionMetrics:
    """One condition's measures: per-FAP statistics (as written) and the head, brow and mouth blocks."""

    faps: dict[str, dict]
    head: HeadMeasures
    brows: BrowMeasures
    mouth: MouthMeasures

    BLOCKS: ClassVar[tuple[str, ...]] = ("head", "brows", "mouth")

    @classmethod
    def from_json(cls, block: Mapping[str, Any]) -> ConditionMetrics:
        return cls({key: value for key, value in block.items() if key not in cls.BLOCKS},
                   HeadMeasures.from_json(block.get("head")), BrowMeasures.from_json(block.get("brows")),
                   MouthMeasures.from_json(block.get("mouth")))

    def to_json(self) -> dict[str, Any]:
        return {**self.faps, "head": self.head.to_json(), "brows": self.brows.to_json(),
                "mouth": self.mouth.to_json()}


@dataclasses.dataclass(frozen=True)
class Controls:
    """The same generator driven by this recording's audio shifted in time (the mismatched-audio control)."""

    head: HeadMeasures
    brows: BrowMeasures
    mouth: MouthMeasures

    @classmethod
    def from_json(cls, block: Mapping[str, Any] | None) -> Controls:
        block = block or {}
        return cls(HeadMeasures.from_json(block.get("mismatched_audio")),
                   BrowMeasures.from_json(block.get("mismatched_audio_brows")),
                   MouthMeasures.from_json(block.get("mismatched_audio_mouth")))

    def to_json(self) -> dict[str, Any]:
        return {"mismatched_audio": self.head.to_json(), "mismatched_audio_brows": self.brows.to_json(),
                "mismatched_audio_mouth": self.mouth.to_json()}


@dataclasses.dataclass(frozen=True)
class Metrics:
    """A comparison's measures, as ``metrics.json`` holds them.

    Attributes
    ----------
    conditions : dict of str to ConditionMetrics
        By condition name (``SPEECH_DRIVEN``, ...), in the comparison's order.
    controls : Controls
        The mismatched-audio controls.
    other_head_models : dict of str to dict
        Head models measured beside the speech-driven one: ``kind``, ``head`` and ``mismatched_audio``.
    settings : dict
        Everything else the document holds (source, frames, seeds, the brows' thresholds, CCA, ...).
    """

    conditions: dict[str, ConditionMetrics]
    controls: Controls
    other_head_models: dict[str, dict[str, Any]]
    settings: dict[str, Any]

    @classmethod
    def from_json(cls, document: Mapping[str, Any]) -> Metrics:
        """Read a metrics document; one of another layout version is refused.

        Parameters
        ----------
        document : mapping
            ``Comparison.metrics``, or ``metrics.json`` parsed.

        Returns
        -------
        Metrics
        """
        version = document.get("version")
        if version != METRICS_VERSION:
            raise ConfigError(f"metrics of layout version {version}: this version of prosody reads version "
                              f"{METRICS_VERSION} (compare again)")
        others = {}
        for label, entry in (document.get("other_head_models") or {}).items():
            others[label] = {"kind": entry.get("kind"), "head": HeadMeasures.from_json(entry.get("head")),
                             "mismatched_audio": HeadMeasures.from_json(entry.get("mismatched_audio"))}
        return cls({name: ConditionMetrics.from_json(block) for name, block in document["conditions"].items()},
                   Controls.from_json(document.get("controls")), others,
                   {key: value for key, value in document.items()
                    if key not in ("conditions", "controls", "other_head_models")})

    def to_json(self) -> dict[str, Any]:
        """The document :meth:`from_json` reads.

        Returns
        -------
        dict
        """
        document = {**self.settings,
                    "conditions": {name: block.to_json() for name, block in self.conditions.items()},
                    "controls": self.controls.to_json()}
        if self.other_head_models:
            document["other_head_models"] = {
                label: {"kind": entry["kind"], "head": entry["head"].to_json(),
                        "mismatched_audio": entry["mismatched_audio"].to_json()}
                for label, entry in self.other_head_models.items()}
        return document
