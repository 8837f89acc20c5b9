"""Atomic file writes: every file the project writes goes to a temporary file in the target's folder first, and is
moved over the target with :func:`os.replace` only once it is complete.

A kill, a Ctrl-C or an error during the write leaves the old target (or none) and no temporary file behind (the
temporary file is removed on any exception; only a hard kill, SIGKILL or power loss, can leave a hidden
``.NAME.*.tmp`` file, never a half-written target).

- :func:`atomic_write`: a context manager that yields an open file (text or binary) to write into;
- :func:`atomic_path`: a context manager that yields a temporary path with the target's suffix, for writers that
  take a path (stable-baselines3's ``model.save``, matplotlib's ``savefig``, video writers);
- :func:`write_text`, :func:`write_json`: the usual one-call cases; :func:`read_json` reads one back with a one-line
  error for a file that is not JSON.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

__all__ = ["atomic_write", "atomic_path", "write_text", "write_json", "read_json"]


def _umask() -> int:
    """The process's umask (read by setting it and putting it back at once)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _finish(tmp: str, path: Path) -> None:
    """Give ``tmp`` the permissions a plainly created file would have, then move it over ``path``."""
    # mkstemp makes the file 0600; a file written by open() gets 0666 less the umask (or keeps the old file's mode).
    try:
        mode = os.stat(path).st_mode & 0o7777
    except OSError:
        mode = 0o666 & ~_umask()
    with contextlib.suppress(OSError):
        os.chmod(tmp, mode)
    os.replace(tmp, path)


def _temp(path: Path, suffix: str) -> tuple[int, str]:
    return tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)


def _remove(tmp: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(tmp)


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w", **open_kwargs: Any) -> Iterator[IO[Any]]:
    """Yield a file opened with ``mode`` (``"w"`` or ``"wb"``; ``open_kwargs`` as :func:`open` takes them) whose
    contents replace ``path`` when the block ends without an exception; on an exception ``path`` is left as it
    was and the temporary file is removed."""
    if mode not in ("w", "wb", "wt", "w+", "wb+", "w+b"):
        raise ValueError(f"atomic_write writes a whole new file: mode must be 'w' or 'wb', got {mode!r}")
    path = Path(path)
    fd, tmp = _temp(path, ".tmp")
    try:
        with os.fdopen(fd, mode, **open_kwargs) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        _finish(tmp, path)
    except BaseException:
        _remove(tmp)
        raise


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder ending in ``path``'s suffix (so writers that infer the format
    from it, or append a missing one, keep it); when the block ends without an exception the file written there
    replaces ``path``. On an exception, or when nothing was written there, ``path`` is left as it was."""
    path = Path(path)
    fd, tmp = _temp(path, f".tmp{path.suffix}")
    os.close(fd)
    try:
        yield Path(tmp)
        if os.path.getsize(tmp) == 0:
            raise OSError(f"nothing was written for {str(path)!r}")
        _finish(tmp, path)
    except BaseException:
        _remove(tmp)
        raise


def write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; returns the path."""
    with atomic_write(path, "w", encoding=encoding) as handle:
        handle.write(text)
    return Path(path)


def write_json(path: str | os.PathLike, data: Any, indent: int | None = 2) -> Path:
    """Write ``data`` as JSON (and a final newline) to ``path`` atomically; returns the path. The text is built
    before the file is touched, so data JSON cannot store leaves the old file as it was."""
    return write_text(path, json.dumps(data, indent=indent) + "\n")


def read_json(path: str | Path, what: str = "JSON file") -> Any:
    """The JSON in ``path``; a file that cannot be read or parsed raises one ValueError naming it (a missing file
    raises FileNotFoundError)."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise FileNotFoundError(f"no {what} at {str(path)!r}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ValueError(f"{path}: unreadable {what} ({err})") from None
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as err:
        raise ValueError(f"{path}: malformed {what} ({err})") from None
