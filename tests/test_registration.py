"""Registration of every map with gymnasium: ids, entry points, limits, kwargs pass-through, a light import."""

import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import smac_hard_gym
from smac_hard_gym.maps import list_maps

# Episode limits of SMAC's map registry (docs/smac_interface.md §7).
SMAC_LIMITS = {
    "3m": 60, "8m": 120, "25m": 150, "5m_vs_6m": 70, "8m_vs_9m": 120, "10m_vs_11m": 150, "27m_vs_30m": 180,
    "MMM": 150, "MMM2": 180, "2s3z": 120, "3s5z": 150, "3s5z_vs_3s6z": 170, "3s_vs_3z": 150, "3s_vs_4z": 200,
    "3s_vs_5z": 250, "1c3s5z": 180, "2m_vs_1z": 150, "corridor": 400, "6h_vs_8z": 150, "2s_vs_1sc": 300,
    "so_many_baneling": 100, "bane_vs_bane": 200, "2c_vs_64zg": 400,
}


def test_every_smac_map_has_an_id():
    ids = {f"SMACHard-{name}-v0" for name in SMAC_LIMITS}
    assert ids <= set(smac_hard_gym.ENV_IDS) and ids <= set(gym.registry)
    assert len(smac_hard_gym.ENV_IDS) == len(set(smac_hard_gym.ENV_IDS))


def test_register_envs_adds_maps_registered_later():
    assert set(smac_hard_gym.register_envs()) == {f"SMACHard-{name}-v0" for name in list_maps()}


@pytest.mark.parametrize("name", sorted(SMAC_LIMITS))
def test_spec_of_each_map(name):
    spec = gym.spec(f"SMACHard-{name}-v0")
    assert spec.entry_point == "smac_hard_gym.envs.gym_env:SMACHardEnv"
    assert spec.vector_entry_point == "smac_hard_gym.envs.vector:NativeVectorEnv"
    assert spec.max_episode_steps == SMAC_LIMITS[name]
    assert spec.kwargs == {"map_name": name}
    assert not spec.nondeterministic


def _run_fresh(code: str) -> str:
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    return result.stdout.strip()


def test_import_is_light():
    out = _run_fresh("import sys, smac_hard_gym; print(sorted(m for m in ('numba', 'torch', 'stable_baselines3') "
                     "if m in sys.modules))")
    assert out == "[]"


def test_make_with_module_prefix_in_a_fresh_process():
    out = _run_fresh("import gymnasium as gym; env = gym.make('smac_hard_gym:SMACHard-3m-v0'); "
                     "obs, info = env.reset(seed=0); print(type(env.unwrapped).__name__, obs.shape, env.action_space)")
    assert out == "SMACHardEnv (90,) MultiDiscrete([9 9 9])"


def test_constructor_kwargs_pass_through():
    env = gym.make("SMACHard-8m-v0", opponent="base", obs_mode="joint+state", invalid_action="raise",
                   reward_sparse=True, obs_last_action=True, backend="native")
    core = env.unwrapped.core
    assert core.opponent.name == "base"
    assert core.options.reward_sparse and core.options.obs_last_action
    assert env.unwrapped.invalid_action == "raise"
    # 8m with obs_last_action: SMAC's obs grows by (n_agents - 1) * n_actions = 7 * 14 columns.
    assert env.observation_space.shape == (8 * (80 + 7 * 14) + 168,)
    env.close()


def test_unknown_kwarg_names_the_allowed_ones():
    with pytest.raises(TypeError, match=r"unknown keyword.*reward_sparce.*opponent_isolation.*reward_sparse"):
        gym.make("SMACHard-3m-v0", reward_sparce=True)


def test_make_vec_uses_the_native_vector_env_and_passes_autoreset_mode():
    from smac_hard_gym.envs.vector import NativeVectorEnv

    envs = gym.make_vec("SMACHard-3m-v0", num_envs=3, autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    assert isinstance(envs, NativeVectorEnv)
    assert envs.metadata["autoreset_mode"] is gym.vector.AutoresetMode.SAME_STEP
    assert envs.num_envs == 3 and envs.episode_limit == 60
    assert envs.spec.id == "SMACHard-3m-v0"
    obs, _ = envs.reset(seed=1)
    assert obs.shape == (3, 90) and obs.dtype == np.float32
    envs.close()
    shorter = gym.make_vec("SMACHard-3m-v0", num_envs=2, max_episode_steps=10)
    assert shorter.episode_limit == 10
    assert shorter.metadata["autoreset_mode"] is gym.vector.AutoresetMode.NEXT_STEP
    shorter.close()


def test_single_and_vector_envs_share_the_invalid_action_default():
    env = gym.make("SMACHard-3m-v0")
    envs = gym.make_vec("SMACHard-3m-v0", num_envs=2)
    assert env.unwrapped.invalid_action == envs.invalid_action == "noop"
    strict = gym.make_vec("SMACHard-3m-v0", num_envs=2, invalid_action="raise")
    assert strict.invalid_action == "raise"
    for e in (env, envs, strict):
        e.close()
