"""The public API is documented: every function and method of the facade (``from prosody import ...``) and every
public one of ``audio_features`` says its Parameters and Returns in numpydoc sections, and the facade's type stub
names what the facade gives."""

from __future__ import annotations

import ast
import importlib
import inspect
import pkgutil

import pytest
from conftest import REPO

import audio_features
import prosody


def _members(qualname: str, value: object):
    yield qualname, value
    if inspect.isclass(value):
        for key, member in vars(value).items():
            if inspect.isfunction(member) and not key.startswith("_"):
                yield f"{qualname}.{key}", member


def public_api() -> list[tuple[str, object]]:
    """Every public function and class of :mod:`audio_features`' modules, and the facade of :mod:`prosody`."""
    found = []
    for info in pkgutil.walk_packages(audio_features.__path__, prefix="audio_features."):
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if name.startswith("_") or getattr(value, "__module__", None) != module.__name__:
                continue
            if inspect.isfunction(value) or (inspect.isclass(value) and not issubclass(value, BaseException)):
                found += _members(f"{module.__name__}.{name}", value)
    for name in prosody._FACADE:
        found += _members(f"prosody.{name}", getattr(prosody, name))
    return found


def missing_sections(target: object) -> list[str]:
    """The numpydoc sections ``target``'s docstring lacks for its signature."""
    doc = inspect.getdoc(target) or ""
    signature = inspect.signature(target)  # type: ignore[arg-type]
    parameters = [p for p in signature.parameters.values() if p.name not in ("self", "cls")]
    returns = not inspect.isclass(target) and signature.return_annotation not in (inspect.Signature.empty, None,
                                                                                "None")
    missing = []
    if parameters and not ("Parameters\n----------" in doc or "Attributes\n----------" in doc):
        missing.append("Parameters")
    if returns and not ("Returns\n-------" in doc or "Yields\n------" in doc):
        missing.append("Returns")
    return missing


@pytest.mark.parametrize(("name", "target"), public_api(), ids=lambda value: value if isinstance(value, str) else "")
def test_the_public_api_says_its_parameters_and_returns(name: str, target: object) -> None:
    assert missing_sections(target) == [], f"{name}: no numpydoc {missing_sections(target)} section"


def test_the_check_can_fail() -> None:
    def undocumented(x: int) -> int:
        """Twice x."""
        return 2 * x

    def documented(x: int) -> int:
        """Twice x.

        Parameters
        ----------
        x : int

        Returns
        -------
        int
        """
        return 2 * x

    assert missing_sections(undocumented) == ["Parameters", "Returns"] and missing_sections(documented) == []


def test_the_facade_stub_names_the_facade() -> None:
    stub = ast.parse((REPO / "prosody" / "__init__.pyi").read_text())
    named = {alias.asname or alias.name for node in ast.walk(stub) if isinstance(node, ast.ImportFrom)
             for alias in node.names}
    named |= {node.name for node in stub.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))}
    assert named >= set(prosody._FACADE)


def test_the_settings_keywords_are_the_groups_fields() -> None:
    """The typed keywords of ``convert``, ``compare`` and ``LiveConverter`` (``**fields: Unpack[...]``) are the
    settings groups' fields, name for name and type for type, so the source a type checker reads cannot drift
    from what the call accepts."""
    import dataclasses

    from prosody.motion.settings import GROUP_FIELDS, FaceSettings, LiveFields, SettingsFields

    def names(group: type) -> dict[str, str]:
        return {f.name: str(f.type) for f in dataclasses.fields(group) if f.init}

    for group, keywords in GROUP_FIELDS.items():
        declared = {name: kind.__forward_arg__ for name, kind in keywords.__annotations__.items()}
        assert declared == names(group), group.__name__
    every = {name for group in GROUP_FIELDS for name in names(group)}
    assert set(SettingsFields.__optional_keys__) == every and not SettingsFields.__required_keys__
    assert set(LiveFields.__optional_keys__) == every - set(names(FaceSettings))

