import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import pytest  # noqa: E402


@pytest.fixture
def validation_calls(monkeypatch):
    """The sides (``"red"``, ``"blue"``) of every action validation the two-player core does while the test runs."""
    from smac_hard_gym.envs import core as core_module

    validate = core_module.validate_actions
    calls: list[str] = []

    def counting(actions, shape, n_actions, who="red"):
        calls.append(who)
        return validate(actions, shape, n_actions, who)

    monkeypatch.setattr(core_module, "validate_actions", counting)
    return calls
