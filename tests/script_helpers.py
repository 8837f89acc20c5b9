"""Import the repository's benchmark scripts (files under benchmarks/, not a package) by path, for tests."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(relative: str, name: str) -> ModuleType:
    """The module at ``benchmarks/<relative>``, imported under ``name``."""
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / relative)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
