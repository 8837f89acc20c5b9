"""MaskablePPO training and masked win-rate evaluation on the native vector env (``smac-hard-gym train`` / ``eval``).

Needs the ``[train]`` extra (torch, stable-baselines3, sb3-contrib, matplotlib); everything heavy is imported inside
the functions, so ``import smac_hard_gym.training`` is cheap.

- :func:`train`: MaskablePPO on a :class:`~smac_hard_gym.envs.vector.NativeVectorEnv` (``SAME_STEP``; with ``ray``,
  a :class:`~smac_hard_gym.wrappers.ray_vec.RayVectorEnv` of ``ray_actors`` actors instead) through the SB3
  adapter, a masked deterministic win-rate evaluation on a schedule, and the run's files in ``out``:
  ``model.zip``, ``config.json``, ``curve.csv`` (timesteps, win rate, return, time inside the env), ``curve.png``
  and ``summary.json``. Time spent in ``env.step`` and ``action_masks`` is measured, so the env's share of the
  wall time is part of every report.
- :func:`evaluate`: win rate of a model over exactly ``episodes`` episodes, per opponent script.

Test protocol (shared by ``train`` and ``eval``): a test evaluation steps ``min(eval_envs, episodes)`` battles seeded
``TEST_SEED_BASE + b`` (battle b; later episodes of a battle continue its generator), whatever the run's seed, so
``train``'s evaluations and ``smac-hard-gym eval`` with its defaults play the same test battles. Training battles
are seeded ``seed + b`` for b < ``num_envs`` (stable-baselines3 seeds the vector env from the run's seed), and a
run's seed is checked to keep them below ``TEST_SEED_BASE``: test and training battles never share a seed. Every
win rate comes with its number of episodes, its standard error and a 95% Wilson interval (:func:`win_rate_spread`).
- :func:`evaluate_scripts`: one evaluation per script of a pool, and the pool's mixture (the paper's black-box
  evaluation when the pool is ``"blackbox"``).
"""

from __future__ import annotations

import contextlib
import csv
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.files import atomic_path, atomic_write, read_json, write_json

__all__ = ["TrainConfig", "EvalResult", "train", "evaluate", "evaluate_scripts", "resolve_opponents",
           "load_run_config", "load_model", "CURVE_COLUMNS", "TEST_SEED_BASE", "eval_seeds",
           "training_seeds", "win_rate_spread"]

CURVE_COLUMNS = ("timesteps", "win_rate", "mean_return", "mean_length", "episodes", "train_win_rate",
                 "train_episodes", "wall_s", "env_s", "env_fraction")
MIXTURE_ROW = "mixture"
POLICIES = ("joint", "shared")  # train --policy
TEST_SEED_BASE = 1_000_000_000  # test battle b is seeded TEST_SEED_BASE + b; training battles stay below it


def eval_seeds(battles: int, base: int = TEST_SEED_BASE) -> list[int]:
    """The seeds of a test evaluation's ``battles`` battles (``min(eval_envs, episodes)`` of them)."""
    return [base + b for b in range(battles)]


def training_seeds(seed: int, num_envs: int) -> list[int]:
    """The seeds of a run's ``num_envs`` training battles: stable-baselines3 seeds the vector env from the run's seed,
    battle b with ``seed + b`` (``VecEnv.seed``)."""
    return [seed + b for b in range(num_envs)]


def win_rate_spread(wins: int, episodes: int, z: float = 1.959964) -> dict[str, Any]:
    """The spread of a win rate over ``episodes`` episodes: ``stderr`` (binomial standard error, sqrt(p(1-p)/n)) and
    ``ci95`` (the 95% Wilson score interval, sensible at 0 and 1 wins too)."""
    if episodes < 1:
        return {"episodes": int(episodes), "stderr": None, "ci95": None}
    p = wins / episodes
    denom = 1 + z * z / episodes
    centre = (p + z * z / (2 * episodes)) / denom
    half = z * math.sqrt(p * (1 - p) / episodes + z * z / (4 * episodes * episodes)) / denom
    return {"episodes": int(episodes), "stderr": math.sqrt(p * (1 - p) / episodes),
            "ci95": [max(0.0, centre - half), min(1.0, centre + half)]}


def format_spread(wins: int, episodes: int) -> str:
    """``"30/32 won, stderr 0.043, 95% CI [0.80, 0.98]"``."""
    spread = win_rate_spread(wins, episodes)
    low, high = spread["ci95"]
    return f"{wins}/{episodes} won, stderr {spread['stderr']:.3f}, 95% Wilson interval [{low:.3f}, {high:.3f}]"


@dataclass
class TrainConfig:
    """Everything a training run depends on (written to ``config.json``)."""

    map_name: str = "3m"
    opponent: str = "default"  # a pool ("default", "blackbox"), a script name, or names joined by commas
    timesteps: int = 50_000
    num_envs: int = 64
    seed: int = 0
    out: str = ""  # default: runs/<map>-<opponent>-s<seed>
    eval_every: int = 0  # env steps between evaluations; 0: a tenth of the run
    eval_episodes: int = 32
    eval_envs: int = 16
    obs_mode: str = "joint"
    policy: str = "joint"  # "joint": the joint MLP (sb3_policy); "shared": the unit-shared MAPPO policy (sb3_shared)
    n_steps: int = 32  # per env and rollout: num_envs * n_steps samples per update
    batch_size: int = 512
    n_epochs: int = 10
    learning_rate: float = 5e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.01
    net_arch: list[int] = field(default_factory=lambda: [128, 128])
    torch_threads: int = 1
    env_threads: int = 1  # numba threads for the engine batch
    progress: bool = True
    tensorboard: str = ""  # a directory for SB3's TensorBoard logs ("" for none; needs the tensorboard package)
    league: bool = False  # self-play league: snapshots of the learner join the opponent's scripts (opponents.league)
    league_every: int = 0  # env steps between snapshots; 0: a fifth of the run
    league_weighting: str = "uniform"  # how members are drawn: "uniform" or "prioritized" (by the learner's losses)
    ray: bool = False  # step the training battles in Ray actors (RayVectorEnv) instead of in this process
    ray_address: str | None = None  # the Ray cluster to join (None: a local Ray, or the one already initialised)
    ray_actors: int = 2  # actors of num_envs / ray_actors battles each

    def __post_init__(self) -> None:
        for name in ("timesteps", "num_envs", "eval_episodes", "eval_envs", "n_steps", "batch_size", "n_epochs",
                     "torch_threads", "env_threads"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a positive int, got {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0 \
                or self.seed + self.num_envs > TEST_SEED_BASE:
            raise ValueError(f"seed must be an int in [0, {TEST_SEED_BASE - self.num_envs}] (training battles are "
                             f"seeded seed + b, below the test seeds from {TEST_SEED_BASE}), got {self.seed!r}")
        if self.eval_every < 0:
            raise ValueError(f"eval_every must be >= 0 (0: a tenth of the run), got {self.eval_every!r}")
        if not self.net_arch or any(int(n) < 1 for n in self.net_arch):
            raise ValueError(f"net_arch must list positive layer sizes, got {self.net_arch!r}")
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if self.policy == "shared" and self.obs_mode == "dict":
            raise ValueError("the shared policy reads the joint view: use obs_mode 'joint+state' (or 'joint')")
        if self.league_every < 0:
            raise ValueError(f"league_every must be >= 0 (0: a fifth of the run), got {self.league_every!r}")
        from smac_hard_gym.opponents.league import WEIGHTINGS

        if self.league_weighting not in WEIGHTINGS:
            raise ValueError(f"league_weighting must be one of {WEIGHTINGS}, got {self.league_weighting!r}")
        if self.ray:
            if isinstance(self.ray_actors, bool) or not isinstance(self.ray_actors, (int, np.integer)) \
                    or self.ray_actors < 1 or self.num_envs % self.ray_actors:
                raise ValueError(f"ray_actors must be a positive int dividing num_envs ({self.num_envs}), got "
                                 f"{self.ray_actors!r}")
            if self.league:
                raise ValueError("--league and --ray cannot be combined: the league lives in the learner's process "
                                 "(snapshots join it and its weights change as the run goes) while Ray actors build "
                                 "their opponents once from a pickled factory; train the league without --ray, or "
                                 "train on Ray against fixed opponents (scripts or saved models)")
        if self.league and self.obs_mode == "dict":
            raise ValueError("league snapshots play from the joint view: use obs_mode 'joint' or 'joint+state'")
        if not self.out:
            label = "+".join(Path(part).stem if part.endswith(".zip") else part.replace(":", "_").replace("/", "_")
                             for part in self.opponent.split(","))
            league = "-league" if self.league else ""
            self.out = str(Path("runs") / f"{self.map_name}-{label}{league}-s{self.seed}")
        if self.tensorboard:
            try:
                import tensorboard  # noqa: F401  (SB3 writes through it)
            except ImportError:
                raise ValueError(f"tensorboard={self.tensorboard!r} needs the tensorboard package: "
                                 "pip install tensorboard") from None

    @property
    def eval_interval(self) -> int:
        return self.eval_every or max(self.timesteps // 10, self.num_envs * self.n_steps)

    @property
    def league_interval(self) -> int:
        return self.league_every or max(self.timesteps // 5, self.num_envs * self.n_steps)

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of the envs this run trains and evaluates on."""
        return {"map_name": self.map_name, "obs_mode": self.obs_mode}

    def ppo_kwargs(self) -> dict[str, Any]:
        """MaskablePPO's keyword arguments for this run's PPO settings (policy, env and buffer apart). The shared
        policy's actor is MAPPO's 64x64; ``net_arch`` sizes its critic, and its layout comes from the map."""
        net_arch: Any = [int(n) for n in self.net_arch]
        policy_kwargs: dict[str, Any] = {"net_arch": net_arch}
        if self.policy == "shared":
            from smac_hard_gym.wrappers.sb3_shared import shared_policy_kwargs

            policy_kwargs = {"net_arch": {"pi": [64, 64], "vf": net_arch},
                             **shared_policy_kwargs(self.map_name, self.obs_mode)}
        return {"n_steps": self.n_steps, "batch_size": self.batch_size, "n_epochs": self.n_epochs,
                "learning_rate": self.learning_rate, "gamma": self.gamma, "gae_lambda": self.gae_lambda,
                "clip_range": self.clip_range, "ent_coef": self.ent_coef, "seed": self.seed, "device": "cpu",
                "verbose": 0, "policy_kwargs": policy_kwargs}


@dataclass
class EvalResult:
    """Masked win rate over ``episodes`` episodes, and per opponent script."""

    episodes: int
    wins: int
    mean_return: float
    mean_length: float
    per_opponent: dict[str, dict[str, float]]

    @property
    def win_rate(self) -> float:
        return self.wins / self.episodes if self.episodes else 0.0

    @property
    def spread(self) -> dict[str, Any]:
        """Episodes, standard error and 95% Wilson interval of the win rate (:func:`win_rate_spread`)."""
        return win_rate_spread(self.wins, self.episodes)


# ---------------------------------------------------------------------------------------------------------------
# Evaluation.


def evaluate(model: Any, venv: Any, episodes: int, *, seed: int | None = None,
             deterministic: bool = True) -> EvalResult:
    """Run ``model`` (anything with SB3's ``predict(obs, action_masks=..., deterministic=...)``) with action masks
    on a ``SAME_STEP`` gymnasium vector env until exactly ``episodes`` episodes have finished.

    Battle i contributes the first ``(episodes + i) // num_envs`` of its episodes, so short episodes are not
    over-counted (the bias of stopping at the first ``episodes`` finishes).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    n = venv.num_envs
    quota = np.array([(episodes + i) // n for i in range(n)])
    counted = np.zeros(n, dtype=np.int64)
    returns = np.zeros(n)
    lengths = np.zeros(n, dtype=np.int64)
    wins, total_return, total_length = 0, 0.0, 0
    per_opponent: dict[str, dict[str, float]] = {}
    obs, _ = venv.reset(seed=seed)
    while (counted < quota).any():
        actions, _ = model.predict(obs, action_masks=venv.action_masks(), deterministic=deterministic)
        obs, rewards, terminated, truncated, infos = venv.step(actions)
        returns += rewards
        lengths += 1
        for i in np.flatnonzero(terminated | truncated):
            if counted[i] < quota[i]:
                final = infos["final_info"]
                won = bool(final["battle_won"][i])
                name = str(final["opponent"][i])
                row = per_opponent.setdefault(name, {"episodes": 0, "wins": 0})
                row["episodes"] += 1
                row["wins"] += won
                wins += won
                total_return += returns[i]
                total_length += lengths[i]
                counted[i] += 1
            returns[i] = 0.0
            lengths[i] = 0
    for row in per_opponent.values():
        row["win_rate"] = row["wins"] / row["episodes"]
    return EvalResult(episodes, wins, total_return / episodes, total_length / episodes,
                      dict(sorted(per_opponent.items())))


def resolve_opponents(map_name: str, opponent: str) -> tuple[list[str], np.ndarray]:
    """The scripts an evaluation covers and their mixture weights: ``"all"`` (every script that plays the map),
    ``"default"`` / ``"blackbox"`` (the map's pools), a script name, or names joined by commas (equal weights)."""
    from smac_hard_gym.opponents import make_opponent, opponent_from_text, scripts_for_map

    if opponent == "all":
        names = sorted(scripts_for_map(map_name))
        return names, np.full(len(names), 1.0 / len(names))
    script = make_opponent(map_name, opponent_from_text(opponent))
    names = getattr(script, "names", None) or [script.name]
    probs = getattr(script, "probs", None)
    return list(names), np.full(len(names), 1.0 / len(names)) if probs is None else np.asarray(probs)


def _evaluate_against(model: Any, map_name: str, opponent: Any, episodes: int, num_envs: int, seed: int,
                      env_kwargs: dict[str, Any] | None) -> EvalResult:
    """:func:`evaluate` on a fresh native vector env of ``map_name`` against one ``opponent``, closed afterwards."""
    from smac_hard_gym.envs.vector import NativeVectorEnv

    kwargs = {k: v for k, v in (env_kwargs or {}).items() if k != "map_name"}
    venv = NativeVectorEnv(map_name, min(num_envs, episodes), autoreset_mode="SameStep", opponent=opponent, **kwargs)
    try:
        return evaluate(model, venv, episodes, seed=seed)
    finally:
        venv.close()


def evaluate_scripts(model: Any, map_name: str, opponent: str, episodes: int, *, num_envs: int = 16,
                     seed: int = TEST_SEED_BASE, env_kwargs: dict[str, Any] | None = None,
                     log: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Evaluate ``model`` for ``episodes`` episodes against each script of ``opponent`` (see
    :func:`resolve_opponents`); the mixture's win rate is the weighted mean of the scripts' (its expectation), its
    standard error ``sqrt(sum(w_i^2 se_i^2))`` and its 95% interval the weighted sum of the scripts' Wilson bounds.
    Each script plays the test battles seeded ``seed + b`` (by default the test seeds that ``train`` evaluates on,
    :data:`TEST_SEED_BASE`)."""
    names, probs = resolve_opponents(map_name, opponent)
    rows: dict[str, dict[str, Any]] = {}
    for name in names:
        result = _evaluate_against(model, map_name, name, episodes, num_envs, seed, env_kwargs)
        spread = result.spread
        rows[name] = {"episodes": result.episodes, "wins": result.wins, "win_rate": result.win_rate,
                      "stderr": spread["stderr"], "ci95": spread["ci95"],
                      "mean_return": result.mean_return, "mean_length": result.mean_length}
        if log is not None:
            log(f"  {name:<20} win rate {result.win_rate:6.3f}  ({format_spread(result.wins, result.episodes)})")
    mixture = float(sum(p * rows[n]["win_rate"] for n, p in zip(names, probs, strict=True)))
    stderr = math.sqrt(sum((p * rows[n]["stderr"]) ** 2 for n, p in zip(names, probs, strict=True)))
    # The weighted sum of the scripts' Wilson bounds: conservative, and never a zero-width interval at 0 or 1.
    ci95 = [float(sum(p * rows[n]["ci95"][k] for n, p in zip(names, probs, strict=True))) for k in (0, 1)]
    return {"map": map_name, "opponent": opponent, "episodes_per_script": episodes, "seed": seed,
            "test_seeds": eval_seeds(min(num_envs, episodes), seed),
            "scripts": rows, "weights": dict(zip(names, (float(p) for p in probs), strict=True)),
            MIXTURE_ROW: {"win_rate": mixture, "stderr": stderr, "ci95": ci95}}


# ---------------------------------------------------------------------------------------------------------------
# Training.


def _timed_vec_env_class() -> type:
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class TimedVecEnv(VecEnvWrapper):
        """Adds up the wall time spent inside the env: ``step_async/step_wait``, ``reset`` and the masks."""

        def __init__(self, venv: Any) -> None:
            super().__init__(venv)
            self.env_seconds = 0.0

        def reset(self) -> Any:
            start = time.perf_counter()
            try:
                return self.venv.reset()
            finally:
                self.env_seconds += time.perf_counter() - start

        def step_async(self, actions: np.ndarray) -> None:
            start = time.perf_counter()
            self.venv.step_async(actions)
            self.env_seconds += time.perf_counter() - start

        def step_wait(self) -> Any:
            start = time.perf_counter()
            try:
                return self.venv.step_wait()
            finally:
                self.env_seconds += time.perf_counter() - start

        def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list[Any]:
            start = time.perf_counter()
            try:
                return self.venv.env_method(method_name, *args, indices=indices, **kwargs)
            finally:
                self.env_seconds += time.perf_counter() - start

    return TimedVecEnv


def _callback_class() -> type:
    from stable_baselines3.common.callbacks import BaseCallback

    class EvalAndProgress(BaseCallback):
        """Progress bar, and a masked win-rate evaluation every ``interval`` steps (plus at the start and end)."""

        def __init__(self, evaluate_now: Callable[..., dict[str, Any]], interval: int, total: int,
                     progress: bool) -> None:
            super().__init__()
            self.evaluate_now = evaluate_now
            self.interval = interval
            self.total = total
            self.progress = progress
            self.bar: Any = None
            self.next_eval = interval
            self.train_results: list[bool] = []

        def take_train_results(self) -> list[bool]:
            results, self.train_results = self.train_results, []
            return results

        def _on_training_start(self) -> None:
            if self.progress:
                import sys

                from tqdm import tqdm

                # SB3 stops at the first whole rollout past the requested steps.
                rollout = self.training_env.num_envs * self.model.n_steps
                total = -(-self.total // rollout) * rollout
                self.bar = tqdm(total=total, unit="step", desc="train", dynamic_ncols=True,
                                mininterval=0.5 if sys.stderr.isatty() else 30.0)

        def _on_step(self) -> bool:
            if self.bar is not None:
                self.bar.update(self.training_env.num_envs)
            for done, info in zip(self.locals["dones"], self.locals["infos"], strict=True):
                if done:  # the sampling policy's own results, between two evaluations
                    self.train_results.append(bool(info.get("is_success", False)))
            if self.num_timesteps >= self.next_eval:
                self.next_eval += self.interval
                row = self.evaluate_now(self.num_timesteps, self.take_train_results())
                if self.bar is not None:
                    self.bar.set_postfix(win_rate=f"{row['win_rate']:.2f}", env=f"{row['env_fraction']:.0%}")
            return True

        def _on_training_end(self) -> None:
            self.close_bar()

        def close_bar(self) -> None:
            """Close the progress bar (at the end of training, or after an interrupt, which skips the end)."""
            if self.bar is not None:
                self.bar.close()
                self.bar = None

    return EvalAndProgress


def _league_callback_class() -> type:
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


def _evaluate_league(model: Any, league: Any, config: TrainConfig, core: Any) -> dict[str, Any]:
    """Win rate of ``model`` against each league member (``config.eval_episodes`` episodes each), with the
    member's drawing probability and its training games."""
    from smac_hard_gym.opponents.policy import PolicyScript

    played = core.stats()["opponents"]
    members = {}
    for member, prob in zip(league.scripts, league.probs, strict=True):
        # A fresh script per evaluation env: members keep per-battle memory sized to the training batch.
        opponent = (PolicyScript(member.policy, member.name, member.options, member.time_limit)
                    if isinstance(member, PolicyScript) else member.name)
        result = _evaluate_against(model, config.map_name, opponent, config.eval_episodes, config.eval_envs,
                                   TEST_SEED_BASE, config.env_kwargs())
        members[member.name] = {"win_rate": result.win_rate, "prob": float(prob),
                                "train_games": int(played.get(member.name, {}).get("games", 0))}
    return {"weighting": league.weighting, "members": members}


def train(config: TrainConfig, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Train MaskablePPO as ``config`` says; returns the summary (also written to ``summary.json``)."""
    with distribution_checks_off():
        return _train(config, log)


@contextlib.contextmanager
def distribution_checks_off() -> Iterator[None]:
    """torch.distributions' argument checks off inside, restored after.

    torch.distributions checks the arguments of every distribution it builds, and MaskablePPO builds two
    Categoricals per agent per forward pass (27 agents on 27m_vs_30m): the checks took about 12% of the training
    time there. They only raise on malformed logits (what comes out does not change).
    """
    from torch.distributions import Distribution

    validate = Distribution._validate_args
    Distribution.set_default_validate_args(False)
    try:
        yield
    finally:
        Distribution.set_default_validate_args(validate)


def _train(config: TrainConfig, log: Callable[[str], None]) -> dict[str, Any]:
    import numba
    import torch
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.vec_env import VecMonitor

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.opponents import opponent_from_text
    from smac_hard_gym.wrappers.sb3 import SB3VecEnv
    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointDictRolloutBuffer, MaskableJointRolloutBuffer
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointMultiInputPolicy, MaskableJointPolicy
    from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy, SharedUnitRolloutBuffer

    torch.set_num_threads(config.torch_threads)
    numba.set_num_threads(min(config.env_threads, numba.config.NUMBA_NUM_THREADS))
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    write_json(out / "config.json", asdict(config))

    opponent = opponent_from_text(config.opponent)
    kwargs = config.env_kwargs()
    map_name = kwargs.pop("map_name")
    league = None
    if config.league:
        from smac_hard_gym.opponents import Mixture, make_opponent
        from smac_hard_gym.opponents.league import League

        start = make_opponent(map_name, opponent)
        league = League(start.scripts if isinstance(start, Mixture) else [start], weighting=config.league_weighting)
    if config.ray:
        from smac_hard_gym.wrappers.ray_vec import make_ray_vec

        native = make_ray_vec(map_name, config.ray_actors, config.num_envs // config.ray_actors,
                              autoreset_mode="SameStep", address=config.ray_address, worker_threads=config.env_threads,
                              opponent=opponent, **kwargs)
        log(f"training battles on Ray: {native!r}")
    else:
        native = NativeVectorEnv(map_name, config.num_envs, autoreset_mode="SameStep",
                                 opponent=opponent if league is None else league, **kwargs)
    timed = _timed_vec_env_class()(SB3VecEnv(native))
    venv = VecMonitor(timed)
    eval_env = NativeVectorEnv(map_name, min(config.eval_envs, config.eval_episodes), autoreset_mode="SameStep",
                               opponent=opponent, **kwargs)
    # sb3-contrib's MlpPolicy / MultiInputPolicy with the joint action as one batched categorical, and its buffers
    # without a second copy of each minibatch: the same weights for the same seed, less training time
    # (wrappers/sb3_policy.py, wrappers/sb3_buffers.py)
    dict_obs = config.obs_mode == "dict"
    policy = MaskableJointMultiInputPolicy if dict_obs else MaskableJointPolicy
    buffer = MaskableJointDictRolloutBuffer if dict_obs else MaskableJointRolloutBuffer
    if config.policy == "shared":  # one actor for every unit, state critic, value normalisation (sb3_shared.py)
        policy, buffer = SharedUnitPolicy, SharedUnitRolloutBuffer
    model = MaskablePPO(policy, venv, rollout_buffer_class=buffer, tensorboard_log=config.tensorboard or None,
                        **config.ppo_kwargs())
    if not config.tensorboard:
        # SB3's default logger makes an empty folder /tmp/SB3-<time> on every learn(), even when it writes nothing.
        from stable_baselines3.common.logger import Logger

        model.set_logger(Logger(folder=None, output_formats=[]))

    rows: list[dict[str, Any]] = []
    clock = {"start": time.perf_counter(), "eval": 0.0}

    def evaluate_now(timesteps: int, train_results: Sequence[bool] = ()) -> dict[str, Any]:
        start = time.perf_counter()
        result = evaluate(model, eval_env, config.eval_episodes, seed=TEST_SEED_BASE)
        clock["eval"] += time.perf_counter() - start
        wall = time.perf_counter() - clock["start"] - clock["eval"]  # training time, evaluations left out
        row = {"timesteps": timesteps, "win_rate": result.win_rate, "mean_return": result.mean_return,
               "mean_length": result.mean_length, "episodes": result.episodes,
               "train_win_rate": float(np.mean(train_results)) if len(train_results) else float("nan"),
               "train_episodes": len(train_results), "wall_s": wall,
               "env_s": timed.env_seconds, "env_fraction": timed.env_seconds / wall if wall > 0 else 0.0,
               "wins": result.wins,
               "per_opponent": {k: v["win_rate"] for k, v in result.per_opponent.items()},
               "per_opponent_episodes": {k: int(v["episodes"]) for k, v in result.per_opponent.items()}}
        rows.append(row)
        _write_curve(out / "curve.csv", rows)
        return row

    progress: Any = _callback_class()(evaluate_now, config.eval_interval, config.timesteps, config.progress)
    callback: Any = progress
    if league is not None:
        from stable_baselines3.common.callbacks import CallbackList

        callback = CallbackList([progress, _league_callback_class()(league, native.core, config.league_interval)])
    evaluate_now(0)
    clock["start"] = time.perf_counter()
    clock["eval"] = 0.0
    timed.env_seconds = 0.0
    interrupted = False
    try:
        model.learn(config.timesteps, callback=callback)
        if rows[-1]["timesteps"] != model.num_timesteps:
            evaluate_now(model.num_timesteps, progress.take_train_results())
    except KeyboardInterrupt:  # Ctrl-C: keep what was learned, the curve so far and a summary that says so
        interrupted = True
    finally:
        # SB3 skips the callback's end on an exception: close the bar here, so it does not draw itself again after
        # the caller's "interrupted" message.
        progress.close_bar()
        venv.close()
        eval_env.close()
    with atomic_path(out / "model.zip") as tmp:
        model.save(tmp)
    plotted = _plot_curve(out / "curve.png", rows, f"MaskablePPO on {config.map_name} vs {config.opponent}")
    summary = _summary(config, rows, int(model.num_timesteps))
    if league is not None and not interrupted:
        league.update(league_win_rates(native.core))
        summary["league"] = _evaluate_league(model, league, config, native.core)
    summary["interrupted"] = interrupted
    summary["timesteps_trained"] = int(model.num_timesteps)
    summary["files"] = {"model": str(out / "model.zip"), "curve_csv": str(out / "curve.csv"),
                        "curve_png": str(out / "curve.png") if plotted else None,
                        "config": str(out / "config.json")}
    write_json(out / "summary.json", summary)
    if summary["final_win_rate"] is not None:
        final = next(r for r in reversed(rows) if r["timesteps"] == summary["final_win_rate_at"])
        log(f"test evaluation at {final['timesteps']} steps: {format_spread(final['wins'], final['episodes'])}; "
            f"{len(summary['test_seeds'])} test battles seeded {summary['test_seeds'][0]}..{summary['test_seeds'][-1]} "
            "(the battles `smac-hard-gym eval` plays by default), training battles seeded "
            f"{config.seed}..{config.seed + config.num_envs - 1}")
    return summary


def _summary(config: TrainConfig, rows: list[dict[str, Any]], trained: int) -> dict[str, Any]:
    """The run's summary: ``timesteps`` is the steps trained (``trained``); ``final_win_rate`` is the last test win
    rate measured after training began and ``final_win_rate_at`` the step count it was measured at (both None when
    the run stopped before its first evaluation after step 0: the untrained model's rate is in ``curve.csv``)."""
    final = rows[-1]
    measured = final if final["timesteps"] > 0 or trained == 0 else None
    reached = next((r["timesteps"] for r in rows if r["win_rate"] >= 0.8), None)
    spread = win_rate_spread(measured["wins"], measured["episodes"]) if measured else \
        {"stderr": None, "ci95": None}
    return {
        "map": config.map_name, "opponent": config.opponent, "timesteps": trained,
        "final_win_rate": measured["win_rate"] if measured else None,
        "final_win_rate_at": measured["timesteps"] if measured else None,
        "best_win_rate": max(r["win_rate"] for r in rows),
        "final_train_win_rate": final["train_win_rate"] if final["train_episodes"] else None,
        "final_train_episodes": final["train_episodes"],
        "first_timesteps_at_0.8": reached, "train_wall_s": final["wall_s"], "env_s": final["env_s"],
        "env_fraction": final["env_fraction"], "final_per_opponent": final["per_opponent"],
        "eval_episodes": config.eval_episodes,
        "final_win_rate_stderr": spread["stderr"], "final_win_rate_ci95": spread["ci95"],
        "final_per_opponent_episodes": final["per_opponent_episodes"],
        "test_seeds": eval_seeds(min(config.eval_envs, config.eval_episodes)),
        "training_seeds": [config.seed, config.seed + config.num_envs - 1],
    }


def _write_curve(path: Path, rows: list[dict[str, Any]]) -> None:
    with atomic_write(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(CURVE_COLUMNS)
        for row in rows:
            writer.writerow([_fmt(row[c]) for c in CURVE_COLUMNS])


def _fmt(value: Any) -> Any:
    if isinstance(value, float):
        return f"{value:.4f}" if math.isfinite(value) else ""
    return value


def _plot_curve(path: Path, rows: list[dict[str, Any]], title: str) -> bool:
    """Win rate and mean return against env steps; False when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    steps = [r["timesteps"] for r in rows]
    fig, left = plt.subplots(figsize=(7, 4), dpi=100)
    left.plot(steps, [r["win_rate"] for r in rows], "o-", color="tab:red", label="test win rate (deterministic)")
    left.plot(steps, [r["train_win_rate"] for r in rows], ".:", color="tab:orange",
              label="training episodes (sampled)")
    left.set_xlabel("env steps")
    left.set_ylabel("win rate")
    left.set_ylim(-0.02, 1.02)
    left.grid(alpha=0.3)
    right = left.twinx()
    right.plot(steps, [r["mean_return"] for r in rows], "s--", color="tab:blue", alpha=0.6, label="mean return")
    right.set_ylabel("mean return")
    left.set_title(title)
    handles = left.get_legend_handles_labels()[0] + right.get_legend_handles_labels()[0]
    left.legend(handles=handles, loc="center right", fontsize="small")
    fig.tight_layout()
    try:
        with atomic_path(path) as tmp:
            fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
    finally:
        plt.close(fig)
    return True


def load_run_config(model_path: str | Path) -> TrainConfig | None:
    """The :class:`TrainConfig` saved next to a model by :func:`train`, if there is one."""
    path = Path(model_path).with_name("config.json")
    if not path.is_file():
        return None
    data = read_json(path, "run config")
    if not isinstance(data, dict):
        raise ValueError(f"{path}: malformed run config (a JSON object of TrainConfig fields expected, got "
                         f"{type(data).__name__})")
    known = {f.name for f in fields(TrainConfig)}
    for key in ("map_name", "opponent", "obs_mode", "policy", "out", "tensorboard", "league_weighting"):
        if key in data and not isinstance(data[key], str):
            raise ValueError(f"{path}: malformed run config ({key} is {data[key]!r}, expected a string)")
    try:
        return TrainConfig(**{k: v for k, v in data.items() if k in known})
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: malformed run config ({err})") from None


def load_model(path: str | Path) -> Any:
    """A MaskablePPO model saved by :func:`train` (``model.zip``), on the CPU; a file that is not one raises one
    ValueError naming it. Loading runs the pickled code the file holds (stable-baselines3's format): load only files
    you trust."""
    from sb3_contrib import MaskablePPO

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no model at {str(path)!r}")
    try:
        return MaskablePPO.load(path, device="cpu")
    except MemoryError:
        raise
    except Exception as err:  # a truncated zip, random bytes, another library's pickle: whatever SB3 raises
        detail = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ValueError(f"{path}: not a saved MaskablePPO model ({type(err).__name__}"
                         f"{': ' + detail if detail else ''})") from None


def format_table(rows: Sequence[tuple[str, ...]]) -> str:
    """Left-aligned text columns."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip() for row in rows)
