"""Value types of the benchmark command lines (``smac-hard-gym bench`` and ``benchmarks/smax_bench.py``).

Standard library only, and nothing from smac-hard-gym: ``benchmarks/smax_bench.py`` runs in a separate Python that
has jaxmarl but not this package, and loads this file by its path, so both command lines parse the same way.
"""

from __future__ import annotations

import argparse

__all__ = ["comma_ints", "comma_names", "map_sizes", "positive_seconds", "positive_int"]


def comma_ints(text: str) -> list[int]:
    """``1,16,256`` -> [1, 16, 256]: positive ints joined by commas."""
    try:
        values = [int(v) for v in text.split(",") if v]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive ints, got {text!r}") from None
    if not values or min(values) < 1:
        raise argparse.ArgumentTypeError(f"expected comma-separated positive ints, got {text!r}")
    return values


def comma_names(text: str) -> list[str]:
    """``3m,8m`` -> ["3m", "8m"]: at least one name."""
    values = [v for v in text.split(",") if v]
    if not values:
        raise argparse.ArgumentTypeError(f"expected comma-separated names, got {text!r}")
    return values


def map_sizes(text: str) -> list[tuple[str, int]]:
    """``3m:4096,8m:256`` -> [("3m", 4096), ("8m", 256)]; an empty string gives none."""
    out = []
    for item in (v for v in text.split(",") if v):
        name, _, size = item.partition(":")
        if not name or not size.isdigit() or int(size) < 1:
            raise argparse.ArgumentTypeError(f"expected MAP:N[,MAP:N...] with N a positive int, got {text!r}")
        out.append((name, int(size)))
    return out


def positive_seconds(text: str) -> float:
    """A positive number of seconds."""
    try:
        value = float(text)
    except ValueError:
        value = 0.0
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """A positive int."""
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive int, got {text!r}")
    return int(text)
