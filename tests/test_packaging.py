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
