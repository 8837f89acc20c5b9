"""User scripts by reference, with no edit to the package.

A reference is one of:

- ``path/to/file.py:ClassName`` — a class (or Script object) in a Python file;
- ``path/to/file.py`` — a file that defines exactly one :class:`Script` subclass;
- ``package.module:Name`` — anything importable on ``sys.path``.

A class is instantiated with no arguments; an object that already is a :class:`Script` is used as it is.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import sys
from pathlib import Path
from types import ModuleType

from smac_hard_gym.opponents.api import Script

__all__ = ["load_script", "is_reference"]


def is_reference(text: str) -> bool:
    """Whether ``text`` names a user script (a file path or ``module:Name``) rather than a built-in name."""
    return ":" in text or _looks_like_path(text)


def _looks_like_path(text: str) -> bool:
    return text.endswith(".py") or "/" in text or "\\" in text


def _split(reference: str) -> tuple[str, str | None]:
    """(file or module, attribute name or None). The last ``:`` separates a name only when a ``.py`` file or a
    dotted module name precedes it, so Windows drive letters (``C:\\...``) survive."""
    head, sep, tail = reference.rpartition(":")
    if sep and head and tail.isidentifier() and (head.endswith(".py") or not _looks_like_path(head)):
        return head, tail
    return reference, None


def _load_file(path: Path) -> ModuleType:
    if not path.is_file():
        raise ValueError(f"user script file {str(path)!r} does not exist")
    digest = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
    module_name = f"smac_hard_gym_user_script_{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ValueError(f"cannot load {str(path)!r} as a Python module")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses and pickling look modules up by name
    try:
        spec.loader.exec_module(module)
    except Exception as err:
        del sys.modules[module_name]
        raise ValueError(f"importing user script file {str(path)!r} failed: {type(err).__name__}: {err}") from err
    return module


def _only_script_class(module: ModuleType, where: str) -> type:
    found = [obj for _, obj in inspect.getmembers(module, inspect.isclass)
             if issubclass(obj, Script) and obj.__module__ == module.__name__ and not inspect.isabstract(obj)]
    if len(found) != 1:
        names = [c.__name__ for c in found]
        raise ValueError(f"{where} must define exactly one Script subclass to load it without a name, found "
                         f"{len(found)} {names}; name one as '{where}:ClassName'")
    return found[0]


def _instantiate(obj: object, reference: str) -> Script:
    if isinstance(obj, Script):
        return obj
    if inspect.isclass(obj) and issubclass(obj, Script):
        try:
            return obj()
        except TypeError as err:
            raise ValueError(f"user script {reference!r}: {obj.__name__}() must be callable without arguments "
                             f"({err})") from err
    raise ValueError(f"user script {reference!r} is {obj!r}, not a Script subclass or Script object "
                     "(see smac_hard_gym.opponents.api.Script)")


def load_script(reference: str) -> Script:
    """Load a user script from ``file.py[:Name]`` or ``module:Name`` (see the module docstring)."""
    if not isinstance(reference, str) or not reference:
        raise ValueError(f"a script reference must be a non-empty string, got {reference!r}")
    target, attr = _split(reference)
    if _looks_like_path(target):
        module = _load_file(Path(target))
        obj = _only_script_class(module, target) if attr is None else getattr(module, attr, None)
        if obj is None:
            raise ValueError(f"user script file {target!r} has no attribute {attr!r}")
        return _instantiate(obj, reference)
    if attr is None:
        raise ValueError(f"{reference!r} is not a script reference; use 'path/to/file.py[:ClassName]' or "
                         "'package.module:ClassName'")
    try:
        module = importlib.import_module(target)
    except ImportError as err:
        raise ValueError(f"cannot import module {target!r} for user script {reference!r}: {err}") from err
    if not hasattr(module, attr):
        raise ValueError(f"module {target!r} has no attribute {attr!r} (user script {reference!r})")
    return _instantiate(getattr(module, attr), reference)
