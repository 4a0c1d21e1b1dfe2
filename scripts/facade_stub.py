"""Write ``prosody/__init__.pyi``, the types of the lazy facade (``python -m scripts.facade_stub``).

Most of the facade is re-exported as it is. The functions and classes that take settings groups
(:func:`prosody.motion.settings.takes_settings`) accept every field of a group as a keyword, which their source
does not spell out; the stub does, from their signatures, so that a type checker checks ``convert(audio,
fps=25)`` as it runs. ``tests/test_api_docs.py`` fails when the stub is not what this writes.
"""

from __future__ import annotations

import builtins
import collections.abc
import importlib
import inspect
import re
import sys
import typing

import prosody

STUB = prosody.__file__.removesuffix(".py") + ".pyi"
#: The first part of each name in an annotation (``os`` of ``os.PathLike``).
NAME = r"(?<![\w.])([A-Za-z_]\w*)"
#: Where names of the settings' annotations live that their modules import only for type checkers.
LOOKUP = ("prosody.motion.eyebrows", "prosody.motion.head_models", "prosody.motion.live", "prosody.motion.settings")


def takes_settings(target: object) -> bool:
    """Whether ``target`` (a function, or a class by its constructor) takes settings groups as keywords."""
    function = target.__init__ if inspect.isclass(target) else target  # type: ignore[misc]
    return hasattr(function, "__wrapped__") and "__signature__" in vars(function)


def _source_of(name: str, home: str) -> str:
    """The import line that brings ``name`` (the first part of a name in an annotation of a function of module
    ``home``) into the stub."""
    if hasattr(builtins, name) or name == "None":
        return ""
    modules = (*LOOKUP, home)  # an alias (not a class) is named from the module of the settings' types first
    found = [(module, getattr(importlib.import_module(module), name)) for module in modules
             if hasattr(importlib.import_module(module), name)]
    if not found:
        raise LookupError(f"{name}: neither {home} nor {', '.join(LOOKUP)} holds it")
    module, value = found[0]
    if inspect.ismodule(value):
        return f"import {value.__name__}"
    if getattr(collections.abc, name, None) is value:
        return f"from collections.abc import {name}"
    if getattr(typing, name, None) is value:
        return f"from typing import {name}"
    defined = getattr(value, "__module__", None) if inspect.isclass(value) or inspect.isfunction(value) else None
    return f"from {defined or module} import {name}"


def _parameters(signature: inspect.Signature, home: str, imports: set[str]) -> str:
    written, keyword_only = [], False
    for parameter in signature.parameters.values():
        if parameter.kind is inspect.Parameter.KEYWORD_ONLY and not keyword_only:
            written.append("*")
            keyword_only = True
        text = parameter.name
        if parameter.annotation is not inspect.Parameter.empty:
            annotation = str(parameter.annotation)
            imports.update(_source_of(name, home) for name in re.findall(NAME, annotation))
            text += f": {annotation}"
        if parameter.default is not inspect.Parameter.empty:
            text += " = ..."
        written.append(text)
    return "".join(f"\n    {text}," for text in written) + "\n"


def _import_block(lines: list[str]) -> list[str]:
    """Import lines as isort writes them: ``import`` first, then ``from`` lines by module, the plain names of one
    module on one line, each re-export (``name as name``) on its own."""
    plain = sorted(line for line in lines if line.startswith("import "))
    names: dict[str, list[str]] = {}
    aliased: list[str] = []
    for line in lines:
        if line.startswith("from "):
            _, module, _, name = line.split(" ", 3)
            if " as " in name:
                aliased.append(line)
            else:
                names.setdefault(module, []).append(name)
    froms = [(module, f"from {module} import {', '.join(sorted(found))}") for module, found in names.items()]
    froms += [(line.split()[1], line) for line in aliased]
    return plain + [line for _, line in sorted(froms, key=lambda item: (item[0], " as " in item[1], item[1]))]


def render() -> str:
    imports: set[str] = set()
    lines: list[str] = []
    for name, module in prosody._FACADE.items():
        target = getattr(importlib.import_module(module), name)
        if not takes_settings(target):
            imports.add(f"from {module} import {name} as {name}")
            continue
        function = target.__init__ if inspect.isclass(target) else target
        home = function.__wrapped__.__module__
        signature = inspect.signature(function)
        if inspect.isclass(target):
            imports.add(f"from {module} import {name} as _{name}")
            parameters = _parameters(signature, home, imports).replace("\n    ", "\n        ")
            lines += ["", "", f"class {name}(_{name}):", f"    def __init__({parameters[:-1]}\n    ) -> None: ..."]
        else:
            returned = str(signature.return_annotation)
            imports.update(_source_of(word, home) for word in re.findall(NAME, returned))
            lines += ["", "", f"def {name}({_parameters(signature, home, imports)}) -> {returned}: ..."]
    header = ['"""Types of the lazy facade of :mod:`prosody` (each name is imported when first asked for). Written by',
              '``python -m scripts.facade_stub``: the functions that take settings groups have their keywords spelled',
              'out."""', ""]
    exported = {line.removesuffix(f" as {line.split()[-1]}") for line in imports if " as " in line}
    wanted = sorted(line for line in imports if line and line not in exported)
    standard = [line for line in wanted if line.split()[1].split(".")[0] in sys.stdlib_module_names]
    ours = [line for line in wanted if line not in standard]
    body = [*_import_block(standard), "", *_import_block(ours), "", "__version__: str", "__all__: list[str]"]
    return "\n".join(header + body + lines) + "\n"


def main() -> int:
    with open(STUB, "w") as handle:
        handle.write(render())
    print(f"{STUB}: written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
