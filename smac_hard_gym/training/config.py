"""A training run's settings: :class:`TrainConfig`, what ``smac-hard-gym train`` parses its options into (and writes
to the run's ``config.json``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.smac.frame_stack import check_frame_stack
from smac_hard_gym.training.mappo_settings import RATIOS, shared_map_defaults
from smac_hard_gym.training.protocol import TEST_SEED_BASE

__all__ = ["TrainConfig", "POLICIES", "REWARDS", "POLICY_DEFAULTS"]

POLICIES = ("joint", "shared")  # train --policy
# train --reward: SMAC's reward as the training battles give it. "positive": SMAC's default (reward_only_positive:
# damage dealt and kills only); "signed": reward_only_positive=False (damage taken, deaths and regenerated shields
# count too, at reward_negative_scale 0.5); "abs": SMAC v1's form of the positive reward, abs(damage + kills), which
# also pays for enemy regeneration and healing (what the SMAC-HARD paper's runs were paid). Test evaluations keep
# smac-hard-gym's default, so test returns compare across runs.
REWARDS = ("positive", "signed", "abs")


def _finite_number(value: Any) -> bool:
    """Whether a numeric setting is a finite int or float (numpy's too; a bool is not a number here)."""
    return not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating)) \
        and bool(np.isfinite(value))


# What each policy trains with unless told otherwise (train's defaults; docs/training_results.md measures them). The
# joint MLP keeps the first sweep's PPO settings. The shared policy takes MAPPO's for SMAC per map
# (mappo_settings.py): 64 battles x 50 steps (MAPPO's 8 threads x 400), the epochs, minibatches and memory of MAPPO's
# launch script for that map, a clip on the joint ratio measured for those epochs, and measured settings where they
# differ; batch_size None: the rollout split into the map's minibatches.
POLICY_DEFAULTS: dict[str, dict[str, Any]] = {
    "joint": {"obs_mode": "joint", "frame_stack": 1, "n_steps": 32, "batch_size": 512, "n_epochs": 10,
              "clip_range": 0.2},
    "shared": {"obs_mode": "joint+state", "batch_size": None},
}


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
    # env steps between checkpoints (checkpoint.zip / .json, what `train --resume` carries on from); 0: only at the end
    checkpoint_every: int = 100_000
    policy: str = "shared"  # "shared": the unit-shared MAPPO policy (sb3_shared); "joint": the joint MLP (sb3_policy)
    # what PPO's clip applies to: "joint" (SB3's MaskablePPO, the whole action's ratio) or "unit" (each unit's,
    # MAPPO's loss: sb3_unit_ppo, the shared policy only)
    ratio: str = "joint"
    # None: the policy's default (POLICY_DEFAULTS), filled in when the config is made
    obs_mode: str | None = None
    frame_stack: int | None = None  # each unit's last k SMAC observations (the envs' frame_stack option)
    # the shared actor also reads its unit's own row of SMAC's global state (weapon cooldown, health, position...);
    # None: the shared policy's default, on where the observation carries the state (obs_mode "joint+state")
    actor_state: bool | None = None
    n_steps: int | None = None  # per env and rollout: num_envs * n_steps samples per update
    batch_size: int | None = None
    n_epochs: int | None = None
    learning_rate: float = 5e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float | None = None
    ent_coef: float = 0.01
    # None: ent_coef throughout; a float: the entropy coefficient falls linearly from ent_coef at step 0 to this at
    # the last step (set before each update)
    ent_coef_final: float | None = None
    # the gradient's global norm is clipped to this before each optimiser step (SB3's default; MAPPO clips the
    # actor's and the critic's gradients at 10 each)
    max_grad_norm: float = 0.5
    reward: str = "positive"  # the training battles' reward (REWARDS); evaluations use SMAC's default
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
        if self.policy not in POLICIES:
            raise ValueError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        defaults = dict(POLICY_DEFAULTS[self.policy])
        minibatches = 1
        if self.ratio not in RATIOS:
            raise ValueError(f"ratio must be one of {RATIOS}, got {self.ratio!r}")
        if self.ratio == "unit" and self.policy != "shared":
            raise ValueError("ratio 'unit' clips each unit's probability ratio, which only the shared policy gives "
                             "(policy 'shared'); the joint MLP trains with ratio 'joint'")
        if self.actor_state is None:  # on where the shared actor has the state to read its row from
            self.actor_state = self.policy == "shared" and (self.obs_mode or defaults["obs_mode"]) == "joint+state"
        if self.policy == "shared":
            per_map = shared_map_defaults(self.map_name, self.ratio, self.actor_state is True)
            minibatches = per_map.pop("minibatches")
            defaults.update(per_map)
        for name, value in defaults.items():
            if getattr(self, name) is None:
                setattr(self, name, value)
        if self.batch_size is None and isinstance(self.n_steps, (int, np.integer)) \
                and isinstance(self.num_envs, (int, np.integer)):
            self.batch_size = max(self.num_envs * self.n_steps // minibatches, 1)  # the rollout in that many parts
        self.frame_stack = check_frame_stack(self.frame_stack)
        if not isinstance(self.actor_state, bool):
            raise ValueError(f"actor_state must be True or False, got {self.actor_state!r}")
        if self.actor_state and (self.policy != "shared" or self.obs_mode != "joint+state"):
            raise ValueError(f"actor_state has the shared actor read its unit's row of the global state: it needs "
                             f"policy 'shared' and obs_mode 'joint+state', got policy {self.policy!r} and obs_mode "
                             f"{self.obs_mode!r}")
        if not isinstance(self.clip_range, (int, float)) or isinstance(self.clip_range, bool) \
                or not 0 < self.clip_range < 1:
            raise ValueError(f"clip_range must be a number in (0, 1), got {self.clip_range!r}")
        for name in ("timesteps", "num_envs", "eval_episodes", "eval_envs", "n_steps", "batch_size", "n_epochs",
                     "torch_threads", "env_threads"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a positive int, got {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0 \
                or self.seed + self.num_envs > TEST_SEED_BASE:
            raise ValueError(f"seed must be an int in [0, {TEST_SEED_BASE - self.num_envs}] (training battles are "
                             f"seeded seed + b, below the test seeds from {TEST_SEED_BASE}), got {self.seed!r}")
        if isinstance(self.checkpoint_every, bool) or not isinstance(self.checkpoint_every, (int, np.integer)) \
                or self.checkpoint_every < 0:
            raise ValueError(f"checkpoint_every must be an int >= 0 (0: at the end only), got "
                             f"{self.checkpoint_every!r}")
        if self.eval_every < 0:
            raise ValueError(f"eval_every must be >= 0 (0: a tenth of the run), got {self.eval_every!r}")
        if not self.net_arch or any(int(n) < 1 for n in self.net_arch):
            raise ValueError(f"net_arch must list positive layer sizes, got {self.net_arch!r}")
        for name in ("ent_coef", "ent_coef_final"):
            value = getattr(self, name)
            if value is None and name == "ent_coef_final":
                continue
            if not _finite_number(value) or value < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not _finite_number(self.max_grad_norm) or self.max_grad_norm <= 0:
            raise ValueError(f"max_grad_norm must be a finite number > 0, got {self.max_grad_norm!r}")
        if self.reward not in REWARDS:
            raise ValueError(f"reward must be one of {REWARDS}, got {self.reward!r}")
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

    def ent_coef_at(self, timesteps: int) -> float:
        """The entropy coefficient of the update made after ``timesteps`` env steps (see ``ent_coef_final``)."""
        if self.ent_coef_final is None:
            return float(self.ent_coef)
        done = min(max(timesteps / self.timesteps, 0.0), 1.0)
        return float(self.ent_coef + (self.ent_coef_final - self.ent_coef) * done)

    def env_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of the envs this run trains and evaluates on."""
        return {"map_name": self.map_name, "obs_mode": self.obs_mode, "frame_stack": self.frame_stack}

    def train_env_kwargs(self) -> dict[str, Any]:
        """:meth:`env_kwargs` plus the training battles' reward options (evaluations use :meth:`env_kwargs`)."""
        kwargs = self.env_kwargs()
        if self.reward == "signed":
            kwargs["reward_only_positive"] = False
        elif self.reward == "abs":
            kwargs["reward_abs"] = True
        return kwargs

    def ppo_kwargs(self) -> dict[str, Any]:
        """MaskablePPO's keyword arguments for this run's PPO settings (policy, env and buffer apart). The shared
        policy's actor is MAPPO's 64x64; ``net_arch`` sizes its critic, and its layout comes from the map."""
        net_arch: Any = [int(n) for n in self.net_arch]
        policy_kwargs: dict[str, Any] = {"net_arch": net_arch}
        if self.policy == "shared":
            from smac_hard_gym.wrappers.sb3_shared import shared_policy_kwargs

            policy_kwargs = {"net_arch": {"pi": [64, 64], "vf": net_arch},
                             **shared_policy_kwargs(self.map_name, self.obs_mode, self.frame_stack,
                                                    own_state=self.actor_state)}
        elif self.frame_stack > 1:
            policy_kwargs["frame_stack"] = self.frame_stack  # recorded with the model for opponents and evaluations
        return {"n_steps": self.n_steps, "batch_size": self.batch_size, "n_epochs": self.n_epochs,
                "learning_rate": self.learning_rate, "gamma": self.gamma, "gae_lambda": self.gae_lambda,
                "clip_range": self.clip_range, "ent_coef": self.ent_coef, "max_grad_norm": self.max_grad_norm,
                "seed": self.seed, "device": "cpu",
                "verbose": 0, "policy_kwargs": policy_kwargs}
