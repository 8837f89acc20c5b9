"""The mixing experiment's value estimate (the paper's section 4.2): the critic's mean value of the first
observation of test episodes, what the learner expects to win from the start."""

from __future__ import annotations

from typing import Any

from smac_hard_gym.files import write_json

__all__ = ["value_estimate", "value_main"]


def value_estimate(model: Any, venv: Any, *, seed: int) -> float:
    """Mean critic value ``model.policy.predict_values`` over the first observations of ``venv``'s battles after
    ``reset(seed=seed)``: what the learner expects to win from the start of a test episode."""
    import torch

    obs, _ = venv.reset(seed=seed)
    with torch.no_grad():
        tensor, _ = model.policy.obs_to_tensor(obs)
        values = model.policy.predict_values(tensor)
    return float(values.mean())


def value_main(model_path: str, opponent: str, episodes: int, seed: int, out: str) -> None:
    """Runs in its own process (:func:`~smac_hard_gym.training.baselines.planning.value_command`):
    :func:`value_estimate` of a trained model on ``episodes`` test battles against ``opponent``, written as JSON to
    ``out``."""
    import torch

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.opponents import opponent_from_text
    from smac_hard_gym.training.run_files import load_model, load_run_config

    torch.set_num_threads(1)
    config = load_run_config(model_path)
    if config is None:
        raise FileNotFoundError(f"no config.json next to {model_path}")
    kwargs = config.env_kwargs()
    map_name = kwargs.pop("map_name")
    model = load_model(model_path)
    venv = NativeVectorEnv(map_name, episodes, autoreset_mode="SameStep", opponent=opponent_from_text(opponent),
                           **kwargs)
    try:
        value = value_estimate(model, venv, seed=seed)  # TEST_SEED_BASE from value_command: train's test battles
    finally:
        venv.close()
    write_json(out, {"map": map_name, "opponent": opponent, "episodes": episodes, "mean_value": value})
