"""A non-editable install must carry every map file and every opponent script (SMAC-HARD's wheel did not)."""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_wheel_contains_maps_scripts_and_subpackages(tmp_path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w",
                    str(tmp_path), str(ROOT)], check=True, capture_output=True)
    wheel = next(tmp_path.glob("smac_hard_gym-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    for map_file in (ROOT / "maps" / "data").glob("*.json"):
        assert f"smac_hard_gym/maps/data/{map_file.name}" in names
    for script in (ROOT / "opponents").glob("*.py"):
        assert f"smac_hard_gym/opponents/{script.name}" in names
    # Every subpackage of the source tree, and every module in it (a package missing from pyproject's list would
    # be left out silently).
    for module in (ROOT / "smac_hard_gym").rglob("*.py"):
        assert f"smac_hard_gym/{module.relative_to(ROOT / 'smac_hard_gym').as_posix()}" in names, module
    assert "smac_hard_gym/wrappers/__init__.py" in names
    # Nothing named maps/opponents/wrappers lands at the top of site-packages.
    assert not any(n.split("/")[0] in ("maps", "opponents", "wrappers", "tests", "examples") for n in names)
    assert any(n.endswith("entry_points.txt") for n in names)
    # The license text travels with the wheel (setuptools picks LICENSE up by default; pyproject says MIT).
    license_files = [n for n in names if n.endswith(".dist-info/licenses/LICENSE")]
    assert len(license_files) == 1, sorted(n for n in names if ".dist-info/" in n)
    text = zipfile.ZipFile(wheel).read(license_files[0]).decode()
    assert text.startswith("MIT License") and "smac-hard-gym contributors" in text


def test_license_and_changelog_are_at_the_root():
    assert (ROOT / "LICENSE").read_text().startswith("MIT License")
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert "## [Unreleased]" in changelog and "## [0.1.0]" in changelog
