"""Self-play league training (``smac-hard-gym train --league``): the learner's side of
:class:`~smac_hard_gym.opponents.league.League`.

The league itself is an opponent (a mixture whose members and weights change) and lives with the opponents; this
module builds it from the run's opponent, adds frozen snapshots of the learner to it on a schedule
(:func:`league_callback_class`), feeds back the learner's win rates from the training env's statistics
(:func:`league_win_rates`), and evaluates the final model against every member (:func:`evaluate_league`).
"""

from __future__ import annotations

from typing import Any

from smac_hard_gym.training.config import TrainConfig
from smac_hard_gym.training.evaluation import evaluate_against
from smac_hard_gym.training.protocol import TEST_SEED_BASE

__all__ = ["make_league", "league_callback_class", "snapshot", "league_win_rates", "evaluate_league"]


def make_league(map_name: str, opponent: Any, weighting: str) -> Any:
    """A :class:`~smac_hard_gym.opponents.league.League` that starts with ``opponent``'s scripts (a mixture's
    members, or the one script)."""
    from smac_hard_gym.opponents import Mixture, make_opponent
    from smac_hard_gym.opponents.league import League

    start = make_opponent(map_name, opponent)
    return League(start.scripts if isinstance(start, Mixture) else [start], weighting=weighting)


def league_callback_class() -> type:
    """``LeagueSnapshots``: the stable-baselines3 callback that re-weighs the league and adds a snapshot of the
    learner every ``interval`` steps."""
    from stable_baselines3.common.callbacks import BaseCallback

    class LeagueSnapshots(BaseCallback):
        """Every ``interval`` steps: the learner's win rates against the league's members so far (from the training
        env's statistics) re-weigh the league, and a frozen copy of the learner joins it."""

        def __init__(self, league: Any, core: Any, interval: int) -> None:
            super().__init__()
            self.league, self.core, self.interval = league, core, interval
            self.next_snapshot = interval

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_snapshot:
                self.next_snapshot += self.interval
                self.league.update(league_win_rates(self.core))
                self.league.add(snapshot(self.model, f"snapshot-{self.num_timesteps}"))
            return True

    return LeagueSnapshots


def snapshot(model: Any, name: str) -> Any:
    """A frozen copy of ``model``'s policy as an opponent (:class:`~smac_hard_gym.opponents.policy.PolicyScript`)."""
    import copy

    from smac_hard_gym.opponents.policy import PolicyScript

    policy = copy.deepcopy(model.policy)
    policy.set_training_mode(False)
    return PolicyScript(policy, name=name)


def league_win_rates(core: Any) -> dict[str, float]:
    """The learner's win rate against each opponent it has finished games with, from a core's statistics."""
    return {name: row["win_rate"] for name, row in core.stats()["opponents"].items() if row["games"]}


def evaluate_league(model: Any, league: Any, config: TrainConfig, core: Any) -> dict[str, Any]:
    """Win rate of ``model`` against each league member (``config.eval_episodes`` episodes each), with the
    member's drawing probability and its training games."""
    from smac_hard_gym.opponents.policy import PolicyScript

    played = core.stats()["opponents"]
    members = {}
    for member, prob in zip(league.scripts, league.probs, strict=True):
        # A fresh script per evaluation env: members keep per-battle memory sized to the training batch.
        opponent = (PolicyScript(member.policy, member.name, member.options, member.time_limit)
                    if isinstance(member, PolicyScript) else member.name)
        result = evaluate_against(model, config.map_name, opponent, config.eval_episodes, config.eval_envs,
                                   TEST_SEED_BASE, config.env_kwargs())
        members[member.name] = {"win_rate": result.win_rate, "prob": float(prob),
                                "train_games": int(played.get(member.name, {}).get("games", 0))}
    return {"weighting": league.weighting, "members": members}
