"""The package's version (one source: pyproject.toml, read from the installed metadata), ``smac-hard-gym --version``,
and ``smac_hard_gym.wrappers``' star import without the optional libraries."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import re
import subprocess
import sys
import textwrap

import pytest

import smac_hard_gym
from smac_hard_gym.cli import main


def test_version_is_the_installed_distributions():
    assert smac_hard_gym.__version__ == importlib.metadata.version("smac-hard-gym")
    assert re.fullmatch(r"\d+\.\d+\.\d+\S*", smac_hard_gym.__version__)
    from smac_hard_gym import __version__

    assert __version__ == smac_hard_gym.__version__


def test_version_falls_back_without_metadata(monkeypatch):
    def missing(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", missing)
    assert smac_hard_gym._read_version() == "0+unknown"


def test_version_flag_prints_the_installed_package_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out == f"smac-hard-gym {smac_hard_gym.__version__}\n"


def test_cli_version_as_a_command():
    done = subprocess.run([sys.executable, "-m", "smac_hard_gym.cli", "--version"], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == f"smac-hard-gym {importlib.metadata.version('smac-hard-gym')}"


def _run_without(blocked: list[str], body: str) -> subprocess.CompletedProcess:
    """Run ``body`` in a fresh interpreter where importing any of ``blocked`` (or a submodule) fails as if the
    library were not installed."""
    code = textwrap.dedent(f"""
        import importlib.abc, sys

        BLOCKED = {blocked!r}

        class Block(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in BLOCKED:
                    raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
                return None

        sys.meta_path.insert(0, Block())
    """) + textwrap.dedent(body)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)


def test_star_import_of_wrappers_works_without_ray():
    done = _run_without(["ray"], """
        from smac_hard_gym.wrappers import *  # noqa: F403
        import smac_hard_gym.wrappers as w

        assert "RayVectorEnv" not in w.__all__ and "make_ray_vec" not in w.__all__, w.__all__
        assert "RayVectorEnv" not in dir() and "make_ray_vec" not in dir()
        assert "ray" not in sys.modules
        for name in ("RayVectorEnv", "make_ray_vec"):
            try:
                exec(f"from smac_hard_gym.wrappers import {name}")
            except ImportError as err:
                assert "smac-hard-gym[ray]" in str(err), err
            else:
                raise AssertionError(f"{name} imported without ray")
        import smac_hard_gym
        try:
            smac_hard_gym.make_ray_vec
        except ImportError as err:
            assert "smac-hard-gym[ray]" in str(err), err
        else:
            raise AssertionError("smac_hard_gym.make_ray_vec resolved without ray")
        print("ok")
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_star_import_of_wrappers_works_without_any_optional_library():
    done = _run_without(["ray", "stable_baselines3"], """
        from smac_hard_gym.wrappers import *  # noqa: F403
        import smac_hard_gym.wrappers as w

        assert w.__all__ == [], w.__all__
        try:
            from smac_hard_gym.wrappers import SB3VecEnv  # noqa: F401
        except ImportError as err:
            assert "smac-hard-gym[train]" in str(err), err
        else:
            raise AssertionError("SB3VecEnv imported without stable_baselines3")
        print("ok")
    """)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "ok"


def test_wrappers_all_lists_what_is_installed():
    import smac_hard_gym.wrappers as w

    expected = [name for name, library in (("SB3VecEnv", "stable_baselines3"), ("RayVectorEnv", "ray"),
                                           ("make_ray_vec", "ray"))
                if importlib.util.find_spec(library) is not None]
    assert w.__all__ == expected
    namespace: dict = {}
    exec("from smac_hard_gym.wrappers import *", namespace)
    assert sorted(k for k in namespace if not k.startswith("__")) == sorted(expected)
    for name in expected:
        assert namespace[name] is getattr(w, name)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        w.nope  # noqa: B018
