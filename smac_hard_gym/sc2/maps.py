"""Where StarCraft II and SMAC-HARD's map files live, and ``smac-hard-gym maps install``.

SMAC-HARD's 23 two-player maps go in ``$SC2PATH/Maps/SMAC_HARD_maps/<name>.SC2Map`` (the folder name is part of the
maps' identity: SMAC's own one-player ``SMAC_Maps`` do not work, they give player 2 no API slot). This repository
ships no map file: users copy them from SMAC-HARD's repository with :func:`install_maps`. Nothing here needs
``pysc2_evolved``, so the command works before the ``[sc2]`` extra is installed.
"""

from __future__ import annotations

import os
import platform
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from smac_hard_gym.maps import SMAC_MAPS
from smac_hard_gym.sc2.errors import MapInstallError, MapNotInstalledError, Sc2NotFoundError

__all__ = [
    "MAP_FOLDER", "MAP_SUFFIX", "Sc2Install", "InstallReport", "find_sc2", "install_maps", "is_map_data",
]

MAP_FOLDER = "SMAC_HARD_maps"
MAP_SUFFIX = ".SC2Map"
_MPQ_MAGIC = (b"MPQ\x1a", b"MPQ\x1b")  # an .SC2Map is an MPQ archive (header or user-data header first)

# pysc2's defaults when SC2PATH is unset, per platform.system().
_DEFAULT_ROOTS = {
    "Linux": "~/StarCraftII",
    "Darwin": "/Applications/StarCraft II",
    "Windows": "C:/Program Files (x86)/StarCraft II",
}

_GET_MAPS = ("get SMAC-HARD's map files (the SMAC_HARD_maps folder of the SMAC-HARD repository, "
             "github.com/devindeng94/smac-hard) and run `smac-hard-gym maps install <folder-or-zip>`")


def is_map_data(head: bytes) -> bool:
    """Whether bytes start like an MPQ archive (every real .SC2Map does)."""
    return head[:4] in _MPQ_MAGIC


@dataclass(frozen=True)
class Sc2Install:
    """A StarCraft II folder: ``root`` and how it was chosen (``source``, for error messages)."""

    root: Path
    source: str

    @property
    def maps_dir(self) -> Path:
        return self.root / "Maps" / MAP_FOLDER

    def map_path(self, name: str) -> Path:
        return self.maps_dir / f"{name}{MAP_SUFFIX}"

    def relative_map_path(self, name: str) -> str:
        """The map's path relative to ``<root>/Maps``, as RequestCreateGame expects it."""
        return f"{MAP_FOLDER}/{name}{MAP_SUFFIX}"

    def installed_maps(self) -> list[str]:
        return [name for name in SMAC_MAPS if self.map_path(name).is_file()]

    def require_map(self, name: str) -> Path:
        """The path of map ``name``; a :class:`MapNotInstalledError` naming the path and the fix if absent."""
        path = self.map_path(name)
        if not path.is_file():
            raise MapNotInstalledError(f"SMAC-HARD map {name!r} is not installed: {path} does not exist; "
                                       f"{_GET_MAPS} (installs into {self.maps_dir})")
        return path


def find_sc2(sc2path: str | os.PathLike | None = None, *, need_versions: bool = True) -> Sc2Install:
    """The StarCraft II folder: ``sc2path``, else ``$SC2PATH``, else the platform default (as pysc2 picks it).

    Raises :class:`Sc2NotFoundError` naming the folder when it does not exist or (``need_versions``) has no
    ``Versions`` folder, which every installed game has.
    """
    if sc2path is not None:
        raw, source = str(sc2path), "the sc2path argument"
    elif os.environ.get("SC2PATH"):
        raw, source = os.environ["SC2PATH"], "the SC2PATH environment variable"
    else:
        raw = _DEFAULT_ROOTS.get(platform.system(), _DEFAULT_ROOTS["Linux"])
        source = "the default location (SC2PATH is not set)"
    root = Path(raw).expanduser()
    fix = ("install StarCraft II (Blizzard's Linux package, or the Battle.net client on Windows/macOS) and point "
           "SC2PATH at its folder, or pass sc2path=...")
    if not root.is_dir():
        raise Sc2NotFoundError(f"StarCraft II not found: {root} (from {source}) is not a folder; {fix}")
    if need_versions and not (root / "Versions").is_dir():
        raise Sc2NotFoundError(f"StarCraft II not found: {root} (from {source}) has no Versions folder, so it is "
                               f"not a game installation; {fix}")
    return Sc2Install(root, source)


@dataclass
class InstallReport:
    """What :func:`install_maps` did: map names installed or already identical, and files skipped with why."""

    target: Path
    installed: list[str] = field(default_factory=list)
    unchanged: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)  # (source file, reason)

    def lines(self) -> list[str]:
        out = [f"target: {self.target}"]
        out += [f"installed  {name}" for name in self.installed]
        out += [f"unchanged  {name}" for name in self.unchanged]
        out += [f"skipped    {source}: {reason}" for source, reason in self.skipped]
        missing = [n for n in SMAC_MAPS if n not in self.installed and n not in self.unchanged
                   and not (self.target / f"{n}{MAP_SUFFIX}").is_file()]
        if missing:
            out.append(f"still missing ({len(missing)}): {', '.join(missing)}")
        return out


_Reader = Callable[[], bytes]


def _candidates(src: Path) -> list[tuple[str, str, _Reader]]:
    """(shown name, file stem, reader) for every .SC2Map in a folder (recursively) or a zip file."""
    if src.is_dir():
        files = sorted(p for p in src.rglob("*") if p.is_file() and p.suffix.lower() == MAP_SUFFIX.lower())
        return [(str(p), p.stem, p.read_bytes) for p in files]
    if zipfile.is_zipfile(src):
        with zipfile.ZipFile(src) as archive:  # maps are small: read them now and close the archive
            members = sorted(m for m in archive.namelist() if m.lower().endswith(MAP_SUFFIX.lower()))
            contents = {m: archive.read(m) for m in members}
        return [(f"{src}!{m}", Path(m).stem, lambda data=contents[m]: data) for m in members]
    raise MapInstallError(f"map source {src} is neither a folder nor a zip file; pass the SMAC_HARD_maps folder "
                          "(or a zip of it)")


def install_maps(src: str | os.PathLike, sc2path: str | os.PathLike | None = None) -> InstallReport:
    """Copy SMAC-HARD's map files from folder or zip ``src`` into ``<SC2 folder>/Maps/SMAC_HARD_maps``.

    Only files named after one of the 23 SMAC maps (``3m.SC2Map`` ...) are taken; others are skipped and reported.
    A file that is not an MPQ archive, or two source files for one map, stop the install before anything is
    written.
    """
    src_path = Path(src).expanduser()
    if not src_path.exists():
        raise MapInstallError(f"map source {src_path} does not exist; {_GET_MAPS}")
    install = find_sc2(sc2path)
    by_lower = {name.lower(): name for name in SMAC_MAPS}
    report = InstallReport(install.maps_dir)
    chosen: dict[str, tuple[str, bytes]] = {}
    problems: list[str] = []
    for shown, stem, read in _candidates(src_path):
        name = stem if stem in SMAC_MAPS else by_lower.get(stem.lower())
        if name is None:
            report.skipped.append((shown, "not one of the 23 SMAC map names"))
            continue
        if name in chosen:
            problems.append(f"two files for map {name!r}: {chosen[name][0]} and {shown}")
            continue
        data = read()
        if not is_map_data(data):
            problems.append(f"{shown} is not an SC2 map (no MPQ header); was it downloaded as a web page?")
            continue
        chosen[name] = (shown, data)
    if problems:
        raise MapInstallError("nothing installed: " + "; ".join(problems))
    if not chosen:
        raise MapInstallError(f"no SMAC-HARD map file (<map name>{MAP_SUFFIX}, e.g. 3m{MAP_SUFFIX}) found in "
                              f"{src_path}; {_GET_MAPS}")
    install.maps_dir.mkdir(parents=True, exist_ok=True)
    for name in sorted(chosen, key=SMAC_MAPS.index):
        target = install.map_path(name)
        data = chosen[name][1]
        if target.is_file() and target.read_bytes() == data:
            report.unchanged.append(name)
            continue
        tmp = target.with_suffix(".part")
        tmp.write_bytes(data)
        tmp.replace(target)  # atomic: a half-written map never carries the real name
        report.installed.append(name)
    return report
