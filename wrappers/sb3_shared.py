"""A unit-shared MAPPO-style policy for MaskablePPO: every unit's SMAC observation goes through one shared actor.

``smac-hard-gym train``'s joint MLP (:mod:`sb3_policy`) reads all units' observations as one vector: its first layer
grows with the square of the unit count (27m_vs_30m: 7.7k inputs) and it must learn every unit's behaviour apart.
:class:`SharedUnitPolicy` is an ordinary sb3-contrib ``MaskableActorCriticPolicy`` (same ``MaskablePPO`` API, saved
and loaded with the model, played by ``eval`` and by :class:`~smac_hard_gym.opponents.policy.PolicyScript`) whose
networks are MAPPO's (Yu et al. 2022, "The Surprising Effectiveness of PPO in Cooperative Multi-Agent Games"):

- **one shared actor**: unit i's logits are ``actor([obs_i, onehot(i), onehot(last_action_i)])``, the same weights
  for every unit (ReLU MLP, ``net_arch["pi"]``, 64x64 by default). The one-hot unit id and last action are appended
  columns of the first layer's weight matrix: the id's columns are added as a per-unit row of that matrix and the
  last action's are multiplied in, which is the concatenation's product without building it. The per-unit logits
  ``(B, n, n_actions)`` are the MultiDiscrete layout flattened, so the joint action is
  :class:`~smac_hard_gym.wrappers.sb3_policy.BatchedMaskableMultiCategorical`, with sb3-contrib's
  ``MaskableMultiCategorical`` semantics (checked by ``tests/test_sb3_shared.py``): rollouts, ``predict`` and
  ``get_distribution`` sample and score through it. PPO's update only needs the log-probabilities of the taken
  actions and the entropies, so :meth:`SharedUnitPolicy.evaluate_actions` computes those in one fused autograd pass
  (masked logsumexp, gather, entropy and their closed-form gradients), equal to sb3-contrib's up to float rounding
  (tested, values and gradients) and about 3.5x faster than building the distribution on 27m_vs_30m minibatches.
  Elsewhere the actor runs unit-major: its first layer is one batched matmul over the units' strided blocks of the
  joint observation, so the 7.7k-wide observation of 27m_vs_30m is not copied into per-unit rows.
- **last actions**: a unit's own last action is not in SMAC's observation (``obs_last_action`` adds the *allies'*
  last actions to the ally features, never the unit's own), but SMAC's global state carries every unit's
  (``state_last_action``, on by default). With ``obs_mode="joint+state"`` the actor reads unit i's one-hot from the
  state's last-action block (``last_action_offset``); with ``obs_mode="joint"`` there is no such block and the
  input is left out (pass ``obs_mode="joint+state"`` to have it).
- **centralised critic** (``critic="state"``): an MLP (``net_arch["vf"]``, 128x128) on SMAC's global state, the tail
  of the ``joint+state`` observation after the ``n_agents * unit_obs_size`` observation columns. ``critic="obs"``
  reads all units' observations instead (what the joint MLP's critic sees; for ``obs_mode="joint"``), and
  ``critic="unit"`` is the decentralised ablation: the actor's network shape, shared, on ``[obs_i, onehot(i)]``,
  averaged over the living units.
- **value normalisation** (``value_norm="running"``, MAPPO's ValueNorm): the critic predicts normalised values and
  every value the policy returns is de-normalised (``mean + std * v``), so GAE, time-limit bootstrapping and
  ``explained_variance`` keep working in reward units. MaskablePPO's loss is fixed (``mse(returns, values)`` on raw
  returns), so :meth:`SharedUnitPolicy.evaluate_actions` returns values whose forward value is de-normalised but whose
  gradient is scaled by ``1 / std`` (``mean + std * v.detach() + (v - v.detach()) / std``): the gradient of the loss
  is exactly that of ``mse((returns - mean) / std, v)``, MAPPO's normalised loss (the logged ``value_loss`` is
  ``std**2`` times it). The running statistics (debiased EMAs of the returns and their squares) live in the policy's
  state dict, so they are saved with ``model.zip``, and are updated once per rollout, after the returns are computed
  and before training on them, by :class:`SharedUnitRolloutBuffer`: the tensor of last values the policy hands
  MaskablePPO for GAE names the policy (``last_values.value_norm_owner``), and the buffer updates it
  with the rollout's returns. Train with ``rollout_buffer_class=SharedUnitRolloutBuffer`` (without it the statistics
  stay at mean 0, std 1, i.e. no normalisation, and a warning says so). ``value_norm="popart"`` also rescales the
  value head on every update so its de-normalised outputs are preserved (PopArt's "ART"); ``"none"`` turns it off.
- **memory** (``frame_stack``): SMAC's observation has no weapon cooldown, so a unit that sees one step cannot tell
  when it can fire again, which kiting needs. With the env's ``frame_stack=k`` (:mod:`~smac_hard_gym.smac.frame_stack`)
  a unit's block is its last k observations, newest first, and the actor reads them all (``unit_obs_size`` = k times
  SMAC's); MAPPO's SMAC runs use a recurrent core, or stacked frames (3s_vs_5z).
- **the unit's own state row** (``own_state_offset``; :func:`shared_policy_kwargs` with ``own_state=True``, which
  ``smac-hard-gym train`` passes unless ``--no-actor-state``): the joint controller's ``joint+state`` observation
  carries SMAC's global state, whose ally rows hold each unit's weapon cooldown (energy for a healer), health,
  shield, type and position from the map's centre. With it the actor also reads unit i's own row, so it knows when
  it can fire without remembering it. MAPPO's and QMIX's decentralised actors never see the state; a joint
  controller does, and this is the part of it that is the unit's own.
- **dead units**: a dead unit's only legal action is no-op, so its masked logits give log-probability 0 and entropy
  0 exactly: it adds nothing to the PPO ratio, the entropy bonus or the actor's gradient (tested). The training pass
  therefore runs the actor on the living units' rows only (a unit is living when an action other than no-op is
  legal), which on a long battle skips a large share of the rows; rollouts and ``predict`` still score every unit
  through the batched categorical. SMAC zeroes a dead unit's observation; the ``"unit"`` critic leaves such rows out
  of its mean.

>>> from sb3_contrib import MaskablePPO
>>> from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy, SharedUnitRolloutBuffer, shared_policy_kwargs
>>> model = MaskablePPO(SharedUnitPolicy, venv, rollout_buffer_class=SharedUnitRolloutBuffer,
...                     policy_kwargs=shared_policy_kwargs(venv))  # doctest: +SKIP

The layout sizes (``unit_obs_size``, ``state_size``, ``last_action_offset``) are policy keyword arguments, saved
with the model; :func:`shared_policy_kwargs` reads them from an env (or a map name and obs mode). Box observations
only (``obs_mode`` "joint" or "joint+state"), with a MultiDiscrete action whose sub-actions have one size.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import torch as th
from gymnasium import spaces
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy
from torch import nn

from smac_hard_gym.smac.frame_stack import check_frame_stack
from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer
from smac_hard_gym.wrappers.sb3_policy import BatchedMaskableMultiCategorical

__all__ = ["SharedUnitPolicy", "SharedUnitRolloutBuffer", "ValueNormaliser", "shared_policy_kwargs", "CRITICS",
           "VALUE_NORMS"]

CRITICS = ("state", "obs", "unit")
VALUE_NORMS = ("running", "popart", "none")


# ---------------------------------------------------------------------------------------------------------------
# Layout.


def shared_policy_kwargs(source: Any, obs_mode: str | None = None, frame_stack: int | None = None,
                         own_state: bool = False, **smac_options: Any) -> dict[str, Any]:
    """``unit_obs_size``, ``state_size``, ``last_action_offset`` and ``frame_stack`` of a joint observation, for
    ``policy_kwargs``; with ``own_state``, also ``own_state_offset`` and ``own_state_size``, the state's ally rows
    (the actor then reads its unit's own row: needs ``obs_mode="joint+state"``).

    ``source``: an env (gymnasium or SB3, vector or single, wrapped or not, with a ``core`` holding SMAC features
    and a ``view`` holding the obs mode and frame stack), a :class:`~smac_hard_gym.smac.features.SideFeatures`, or a
    map name (then ``obs_mode``, default "joint+state", ``frame_stack``, default 1, and any SMAC options as keywords).
    """
    from smac_hard_gym.smac.features import SideFeatures

    feats = source if isinstance(source, SideFeatures) else None
    if feats is None and isinstance(source, str):
        from smac_hard_gym.engine.state import RED
        from smac_hard_gym.maps import load_map
        from smac_hard_gym.smac.features import SmacOptions

        feats = SideFeatures(load_map(source), RED, SmacOptions(**smac_options))
        obs_mode = obs_mode or "joint+state"
    elif feats is None:
        env = _find_env(source)
        feats = env.core.features[0]
        obs_mode = obs_mode or env.view.obs_mode
        frame_stack = env.view.frame_stack if frame_stack is None else frame_stack
    obs_mode = obs_mode or "joint+state"
    frame_stack = check_frame_stack(1 if frame_stack is None else frame_stack)
    if obs_mode not in ("joint", "joint+state"):
        raise ValueError(f"the shared policy reads Box observations: obs_mode 'joint' or 'joint+state', got "
                         f"{obs_mode!r}")
    n, size = feats.n_agents, feats.obs_size * frame_stack
    with_state = obs_mode == "joint+state"
    opt = feats.options
    has_actions = with_state and opt.state_last_action and not opt.obs_instead_of_state
    kwargs = {"unit_obs_size": int(size), "state_size": int(feats.state_size) if with_state else 0,
              "last_action_offset": int(n * size + feats.state_action_offset) if has_actions else None,
              "frame_stack": frame_stack}
    if own_state:
        if not with_state or opt.obs_instead_of_state:
            raise ValueError(f"own_state reads the unit's row of SMAC's global state: it needs obs_mode "
                             f"'joint+state' with SMAC's state (not obs_instead_of_state), got obs_mode {obs_mode!r}")
        kwargs.update(own_state_offset=int(n * size), own_state_size=int(feats.ally_state_feats))
    return kwargs


def _find_env(env: Any) -> Any:
    """The env under SB3/gymnasium wrappers that has SMAC features (``core.features``) and a joint ``view``."""
    seen = 0
    while env is not None and seen < 32:
        if hasattr(env, "core") and hasattr(env, "view"):
            return env
        env = getattr(env, "venv", None) or getattr(env, "env", None) or getattr(env, "unwrapped", None)
        seen += 1
    raise TypeError("no SMAC env found under the given wrappers: pass shared_policy_kwargs a map name and obs_mode")


# ---------------------------------------------------------------------------------------------------------------
# Value normalisation.


class ValueNormaliser(nn.Module):
    """Running mean and std of the value targets (MAPPO's ValueNorm: debiased EMAs of x and x**2, ``beta`` per
    update); identity until the first update. Buffers, so they are saved in the policy's state dict."""

    def __init__(self, beta: float = 0.99999, epsilon: float = 1e-5, min_var: float = 1e-2) -> None:
        super().__init__()
        self.beta, self.epsilon, self.min_var = float(beta), float(epsilon), float(min_var)
        self.register_buffer("running_mean", th.zeros((), dtype=th.float64))
        self.register_buffer("running_mean_sq", th.zeros((), dtype=th.float64))
        self.register_buffer("debiasing_term", th.zeros((), dtype=th.float64))
        self.register_buffer("updates", th.zeros((), dtype=th.int64))

    def stats(self) -> tuple[float, float]:
        """(mean, std) as floats: (0, 1) before the first update."""
        if int(self.updates) == 0:
            return 0.0, 1.0
        debias = max(float(self.debiasing_term), self.epsilon)
        mean = float(self.running_mean) / debias
        var = max(float(self.running_mean_sq) / debias - mean * mean, self.min_var)
        return mean, math.sqrt(var)

    @th.no_grad()
    def update(self, targets: Any) -> tuple[tuple[float, float], tuple[float, float]]:
        """Fold a batch of targets in; returns the (mean, std) before and after."""
        before = self.stats()
        x = th.as_tensor(np.asarray(targets), dtype=th.float64).flatten()
        b = self.beta
        self.running_mean.mul_(b).add_((1 - b) * x.mean())
        self.running_mean_sq.mul_(b).add_((1 - b) * (x * x).mean())
        self.debiasing_term.mul_(b).add_(1 - b)
        self.updates.add_(1)
        return before, self.stats()


class SharedUnitRolloutBuffer(MaskableJointRolloutBuffer):
    """:class:`~smac_hard_gym.wrappers.sb3_buffers.MaskableJointRolloutBuffer` that updates the value normaliser of
    the policy that computed the rollout's last values with the rollout's returns (see the module docstring)."""

    def compute_returns_and_advantage(self, last_values: th.Tensor, dones: np.ndarray) -> None:
        super().compute_returns_and_advantage(last_values, dones)
        owner = getattr(last_values, "value_norm_owner", None)
        if owner is not None:
            owner.update_value_normaliser(self.returns)


# ---------------------------------------------------------------------------------------------------------------
# The policy.


class SharedUnitPolicy(MaskableActorCriticPolicy):
    """One actor shared by every unit, a centralised critic and value normalisation (see the module docstring).

    ``unit_obs_size``: one unit's observation block, its SMAC observation times ``frame_stack`` (default: the
    observation size over ``n_agents``, for ``obs_mode="joint"``); ``frame_stack``: the env's ``frame_stack`` the
    blocks come from (saved with the model, so opponents and evaluations rebuild the same observation);
    ``state_size``: the global state's size at the end of the observation (0: none); ``last_action_offset``: where the
    state's ``n_agents * n_actions`` last-action block starts in the observation (None: no last-action input);
    ``own_state_offset``, ``own_state_size``: where the state's ``n_agents`` ally rows of ``own_state_size`` values
    start in the observation, for an actor that reads its unit's own row (None: it does not). ``unit_ids``: append
    the one-hot unit id. ``critic``: "state", "obs" or "unit". ``value_norm``: "running",
    "popart" or "none". ``net_arch``: a list (both networks) or ``dict(pi=..., vf=...)``; default ``dict(pi=[64, 64],
    vf=[128, 128])``. ReLU by default, orthogonal initialisation as SB3's.
    """

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Space, lr_schedule: Any,
                 net_arch: list[int] | dict[str, list[int]] | None = None,
                 activation_fn: type[nn.Module] = nn.ReLU, *args: Any, unit_obs_size: int | None = None,
                 state_size: int = 0, last_action_offset: int | None = None, unit_ids: bool = True,
                 last_action: bool = True, critic: str | None = None, value_norm: str = "running",
                 value_norm_beta: float = 0.99999, frame_stack: int = 1, own_state_offset: int | None = None,
                 own_state_size: int = 0, **kwargs: Any) -> None:
        """SB3's policy constructor (spaces, schedule, ``net_arch``, activation and its own keywords passed through),
        then this policy's options by keyword: SB3 saves a policy's constructor keywords with ``model.zip`` and
        rebuilds it from them (``policy_kwargs``), so each option is a flat keyword, hence the long list."""
        if not isinstance(action_space, spaces.MultiDiscrete) or len(set(action_space.nvec.tolist())) != 1:
            raise ValueError(f"SharedUnitPolicy needs a MultiDiscrete action of equal sub-actions, got {action_space}")
        if not isinstance(observation_space, spaces.Box) or len(observation_space.shape) != 1:
            raise ValueError(f"SharedUnitPolicy reads a flat Box observation (obs_mode 'joint' or 'joint+state'), "
                             f"got {observation_space}")
        n, n_actions = len(action_space.nvec), int(action_space.nvec[0])
        dim = int(observation_space.shape[0])
        if unit_obs_size is None:
            if state_size or dim % n:
                raise ValueError("pass unit_obs_size (see shared_policy_kwargs) when the observation carries a state")
            unit_obs_size = dim // n
        if n * int(unit_obs_size) + int(state_size) != dim:
            raise ValueError(f"{n} units x {unit_obs_size} + state {state_size} != the observation's {dim} values: "
                             "were the sizes read from this env (shared_policy_kwargs)?")
        if last_action_offset is not None and not (n * unit_obs_size <= last_action_offset
                                                   and last_action_offset + n * n_actions <= dim):
            raise ValueError(f"last_action_offset {last_action_offset} does not fit a {n}x{n_actions} block inside "
                             f"the state of the {dim}-value observation")
        if own_state_offset is not None and not (
                own_state_size > 0 and n * unit_obs_size <= own_state_offset
                and own_state_offset + n * own_state_size <= dim):
            raise ValueError(f"own_state_offset {own_state_offset} with own_state_size {own_state_size} does not fit "
                             f"{n} rows inside the state of the {dim}-value observation")
        frame_stack = check_frame_stack(frame_stack)
        if unit_obs_size % frame_stack:
            raise ValueError(f"unit_obs_size {unit_obs_size} is not frame_stack {frame_stack} frames of one size")
        self.frame_stack = frame_stack
        critic = critic or ("state" if state_size else "obs")
        if critic not in CRITICS:
            raise ValueError(f"critic must be one of {CRITICS}, got {critic!r}")
        if critic == "state" and not state_size:
            raise ValueError("critic='state' needs the global state in the observation (obs_mode 'joint+state')")
        if value_norm not in VALUE_NORMS:
            raise ValueError(f"value_norm must be one of {VALUE_NORMS}, got {value_norm!r}")
        self.n_units, self.n_unit_actions = n, n_actions
        self.unit_obs_size, self.state_size = int(unit_obs_size), int(state_size)
        self.last_action_offset = None if last_action_offset is None else int(last_action_offset)
        self.own_state_offset = None if own_state_offset is None else int(own_state_offset)
        self.own_state_size = int(own_state_size) if own_state_offset is not None else 0
        self.unit_ids, self.last_action = bool(unit_ids), bool(last_action)
        self.critic, self.value_norm, self.value_norm_beta = critic, value_norm, float(value_norm_beta)
        if net_arch is None:
            net_arch = {"pi": [64, 64], "vf": [128, 128]}
        super().__init__(observation_space, action_space, lr_schedule, net_arch, activation_fn, *args, **kwargs)

    # -- construction ----------------------------------------------------------------------------------------------

    @property
    def uses_last_action(self) -> bool:
        return self.last_action and self.last_action_offset is not None

    @property
    def uses_own_state(self) -> bool:
        return self.own_state_offset is not None

    def _state_blocks(self) -> list[tuple[int, int]]:
        """(offset, width) of the per-unit blocks of the state the actor reads after a unit's observation and id, in
        its first layer's column order: the unit's last action (one-hot), then its own state row."""
        blocks = [(self.last_action_offset, self.n_unit_actions)] if self.uses_last_action else []
        return blocks + ([(self.own_state_offset, self.own_state_size)] if self.uses_own_state else [])

    def _arch(self, key: str) -> list[int]:
        arch = self.net_arch[key] if isinstance(self.net_arch, dict) else self.net_arch
        return [int(h) for h in arch]

    def _build(self, lr_schedule: Any) -> None:
        n, o, a = self.n_units, self.unit_obs_size, self.n_unit_actions
        self.action_dist = BatchedMaskableMultiCategorical([a] * n)
        pi = self._arch("pi")
        # The actor's first layer: one weight matrix over [obs_i, onehot(i), onehot(last_action_i), state row_i].
        width = o + (n if self.unit_ids else 0) + sum(w for _, w in self._state_blocks())
        first, rest = (pi[0], pi[1:]) if pi else (None, [])
        if first is None:
            raise ValueError("net_arch['pi'] needs at least one hidden layer")
        self.actor_in = nn.Linear(width, first)
        self.actor_activation = _in_place(self.activation_fn)()
        self.actor_body = _mlp(first, rest, _in_place(self.activation_fn))
        self.action_net = nn.Linear(rest[-1] if rest else first, a)
        vf = self._arch("vf")
        if self.critic == "unit":
            critic_in = o + (n if self.unit_ids else 0)
        else:
            critic_in = self.state_size if self.critic == "state" else n * o
        self.critic_body = _mlp(critic_in, vf, self.activation_fn)
        self.value_net = nn.Linear(vf[-1] if vf else critic_in, 1)
        self.value_normaliser = ValueNormaliser(self.value_norm_beta)
        self._warned_no_update = False
        if self.ortho_init:
            for module, gain in ((self.actor_in, math.sqrt(2)), (self.actor_body, math.sqrt(2)),
                                 (self.critic_body, math.sqrt(2)), (self.action_net, 0.01), (self.value_net, 1.0)):
                module.apply(lambda m, g=gain: self.init_weights(m, gain=g))
        self.optimizer = self.optimizer_class(self.parameters(), lr=lr_schedule(1), **self.optimizer_kwargs)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(unit_obs_size=self.unit_obs_size, state_size=self.state_size,
                    last_action_offset=self.last_action_offset, unit_ids=self.unit_ids, last_action=self.last_action,
                    critic=self.critic, value_norm=self.value_norm, value_norm_beta=self.value_norm_beta,
                    frame_stack=self.frame_stack, own_state_offset=self.own_state_offset,
                    own_state_size=self.own_state_size)
        return data

    # -- the networks ----------------------------------------------------------------------------------------------

    def _flat(self, obs: th.Tensor) -> th.Tensor:
        return super().extract_features(obs, self.features_extractor)

    def unit_observations(self, x: th.Tensor) -> th.Tensor:
        """(B, n_units, unit_obs_size) view of a flat joint observation."""
        return x[:, :self.n_units * self.unit_obs_size].reshape(x.shape[0], self.n_units, self.unit_obs_size)

    def unit_last_actions(self, x: th.Tensor) -> th.Tensor | None:
        """(B, n_units, n_actions) one-hot last actions from the state, or None."""
        if not self.uses_last_action:
            return None
        start = self.last_action_offset
        block = x[:, start:start + self.n_units * self.n_unit_actions]
        return block.reshape(x.shape[0], self.n_units, self.n_unit_actions)

    def _by_unit(self, x: th.Tensor, start: int, width: int) -> th.Tensor:
        """(n_units, B, width) strided view of the per-unit blocks of ``width`` values from column ``start`` (unit u
        at ``start + u * width``): each unit's (B, width) slice is a plain matrix to BLAS, so no copy is made."""
        x = x.contiguous()
        return x.as_strided((self.n_units, x.shape[0], width), (width, x.stride(0), 1), x.storage_offset() + start)

    def unit_major_logits(self, x: th.Tensor) -> th.Tensor:
        """(n_units, B, n_actions) logits: the shared actor on every unit's [obs, onehot(id), onehot(last action),
        own state row].

        Unit-major, as the batched categorical lays its rows out; the first layer is one batched matmul over the
        units' strided observation blocks (no copy of the 7.7k-wide joint observation on 27m_vs_30m)."""
        o, n = self.unit_obs_size, self.n_units
        weight = self.actor_in.weight
        width = weight.shape[0]
        bias = self.actor_in.bias.view(1, 1, width)
        col = o
        if self.unit_ids:  # onehot(i) @ W_id.T is W_id's column i: one row per unit, broadcast over the batch
            bias = bias + weight[:, col:col + n].t().unsqueeze(1)
            col += n
        hidden = th.baddbmm(bias, self._by_unit(x, 0, o), weight[:, :o].t().expand(n, o, width))
        for start, w in self._state_blocks():
            hidden = th.baddbmm(hidden, self._by_unit(x, start, w), weight[:, col:col + w].t().expand(n, w, width))
            col += w
        return self.action_net(self.actor_body(self.actor_activation(hidden)))

    def unit_rows_logits(self, x: th.Tensor, b: th.Tensor, u: th.Tensor) -> th.Tensor:
        """(k, n_actions) logits of unit ``u[i]`` in battle ``b[i]``: :meth:`unit_major_logits`'s rows, computed for
        those units only (their observation rows are gathered, the rest never enter the network)."""
        o, n = self.unit_obs_size, self.n_units
        weight = self.actor_in.weight
        bias = self.actor_in.bias
        col = o
        if self.unit_ids:
            bias = bias + weight[:, col:col + n].t()[u]  # (k, width): unit u's id column
            col += n
        hidden = th.addmm(bias, self._by_unit(x, 0, o)[u, b], weight[:, :o].t())
        for start, w in self._state_blocks():
            hidden = th.addmm(hidden, self._by_unit(x, start, w)[u, b], weight[:, col:col + w].t())
            col += w
        return self.action_net(self.actor_body(self.actor_activation(hidden)))

    def unit_logits(self, x: th.Tensor) -> th.Tensor:
        """(B, n_units, n_actions) logits (a view of :meth:`unit_major_logits`)."""
        return self.unit_major_logits(x).transpose(0, 1)

    def action_logits(self, obs: th.Tensor) -> th.Tensor:
        """(B, n_units * n_actions) logits in the MultiDiscrete layout."""
        logits = self.unit_logits(self._flat(obs))
        return logits.reshape(logits.shape[0], -1)

    def normalised_values(self, x: th.Tensor) -> th.Tensor:
        """(B, 1): the critic's output, in normalised units."""
        if self.critic == "state":
            start = self.n_units * self.unit_obs_size
            return self.value_net(self.critic_body(x[:, start:start + self.state_size]))
        if self.critic == "obs":
            return self.value_net(self.critic_body(x[:, :self.n_units * self.unit_obs_size]))
        units = self.unit_observations(x)
        inputs = units
        if self.unit_ids:
            eye = th.eye(self.n_units, dtype=x.dtype, device=x.device).expand(x.shape[0], -1, -1)
            inputs = th.cat([units, eye], dim=2)
        per_unit = self.value_net(self.critic_body(inputs)).squeeze(-1)  # (B, n)
        alive = (units != 0).any(dim=2)
        alive = th.where(alive.any(dim=1, keepdim=True), alive, th.ones_like(alive))  # all dead: average them all
        weights = alive.to(per_unit.dtype)
        return ((per_unit * weights).sum(dim=1) / weights.sum(dim=1)).unsqueeze(-1)

    def _denormalised(self, values: th.Tensor, train: bool = False) -> th.Tensor:
        if self.value_norm == "none":
            return values
        mean, std = self.value_normaliser.stats()
        if not train:
            return values * std + mean
        # forward value mean + std * v; gradient of mse(returns, .) equal to that of mse((returns - mean) / std, v)
        detached = values.detach()
        return mean + std * detached + (values - detached) / std

    def update_value_normaliser(self, returns: Any) -> None:
        """Fold a rollout's returns into the normaliser (PopArt also rescales the value head to keep its outputs)."""
        if self.value_norm == "none":
            return
        (old_mean, old_std), (mean, std) = self.value_normaliser.update(returns)
        if self.value_norm == "popart":
            with th.no_grad():
                self.value_net.weight.mul_(old_std / std)
                self.value_net.bias.mul_(old_std).add_(old_mean - mean).div_(std)

    # -- sb3-contrib's interface -----------------------------------------------------------------------------------

    def _distribution(self, x: th.Tensor, action_masks: Any) -> BatchedMaskableMultiCategorical:
        logits = self.action_logits(x)
        distribution = self.action_dist.proba_distribution(action_logits=logits)
        if action_masks is not None:
            distribution.apply_masking(action_masks)
        return distribution

    def forward(self, obs: th.Tensor, deterministic: bool = False,
                action_masks: np.ndarray | None = None) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        x = self._flat(obs)
        distribution = self._distribution(x, action_masks)
        actions = distribution.get_actions(deterministic=deterministic)
        log_prob = distribution.log_prob(actions)
        values = self._denormalised(self.normalised_values(x))
        return actions.reshape((-1, *self.action_space.shape)), values, log_prob

    def evaluate_actions(self, obs: th.Tensor, actions: th.Tensor,
                         action_masks: th.Tensor | None = None) -> tuple[th.Tensor, th.Tensor, th.Tensor]:
        values, log_prob, entropy, _ = self.evaluate_unit_actions(obs, actions, action_masks)
        return values, log_prob.sum(dim=1), entropy.sum(dim=1)

    def evaluate_unit_actions(self, obs: th.Tensor, actions: th.Tensor, action_masks: th.Tensor | None = None
                              ) -> tuple[th.Tensor, th.Tensor, th.Tensor, th.Tensor]:
        """The values (B, 1), and per unit (B, n_units) the log-probability of its action, its entropy and whether
        it is living (an action other than no-op legal); a dead unit's log-probability and entropy are 0. The joint
        log-probability and entropy (:meth:`evaluate_actions`) are their sums over the units."""
        if self.value_norm != "none" and int(self.value_normaliser.updates) == 0 and not self._warned_no_update:
            self._warned_no_update = True
            warnings.warn("SharedUnitPolicy trains without value normalisation statistics: pass "
                          "rollout_buffer_class=SharedUnitRolloutBuffer to MaskablePPO (or value_norm='none')",
                          stacklevel=3)
        x = self._flat(obs)
        batch, n, a = x.shape[0], self.n_units, self.n_unit_actions
        if action_masks is None:
            legal = th.ones(batch, n, a, dtype=th.bool, device=x.device)
        else:
            legal = th.as_tensor(action_masks, dtype=th.bool, device=x.device).reshape(batch, n, a)
        # A dead unit (no-op its only legal action) has log-probability 0, entropy 0 and no gradient whatever its
        # logits: the actor runs on the living units' rows only (about half of them on a long battle)
        living = legal[:, :, 1:].any(dim=2)
        b, u = living.nonzero(as_tuple=True)
        rows = _MaskedUnitLogProbEntropy.apply(self.unit_rows_logits(x, b, u), legal[b, u],
                                               actions.reshape(batch, n)[b, u])
        zeros = th.zeros(batch, n, dtype=x.dtype, device=x.device)
        log_prob, entropy = (zeros.index_put((b, u), values) for values in rows)
        values = self._denormalised(self.normalised_values(x), train=True)
        return values, log_prob, entropy, living

    def get_distribution(self, obs: th.Tensor, action_masks: np.ndarray | None = None) -> Any:
        return self._distribution(self._flat(obs), action_masks)

    def predict_values(self, obs: th.Tensor) -> th.Tensor:
        values = self._denormalised(self.normalised_values(self._flat(obs)))
        values.value_norm_owner = self  # read by SharedUnitRolloutBuffer (see the module docstring)
        return values


class _MaskedUnitLogProbEntropy(th.autograd.Function):
    """Per row: the log-probability of ``actions`` (k,) and the entropy of the masked categoricals of ``logits``
    (k, A) under ``legal`` (k, A), in one pass forward and one backward (PPO's training loss needs nothing else;
    sampling in rollouts and ``predict`` goes through the batched categorical).

    sb3-contrib's values: an illegal action's logit is -1e8, so its probability is 0 and it adds 0 to the entropy; a
    sampled illegal action's log-probability is ``-1e8 - logsumexp`` (sb3-contrib's also depends on the unmasked
    logits there: PPO never scores an action its masks forbid). Computed as ``lse = m + log(sum(e))`` with
    ``e = exp(clamp(logits - m, -87, 0)) * legal`` and ``m`` the largest legal logit: legal terms below e**-87 are
    rounded up to it, which keeps torch's exp on its fast path and changes no sum (the largest term is 1) by a
    representable amount. The entropy is ``lse - sum(p * logits)``; gradients ``onehot(a) - p`` and
    ``-p * (log p + H)``, zero at illegal actions. A unit with one legal action (a dead one) gets exactly 0: its
    ``m`` is its logit, its ``p`` is 1.
    """

    @staticmethod
    def forward(ctx: Any, logits: th.Tensor, legal: th.Tensor, actions: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        neg = th.tensor(-1e8, dtype=logits.dtype, device=logits.device)
        top = th.where(legal, logits, neg).amax(dim=-1, keepdim=True)  # the largest legal logit
        e = (logits - top).clamp_(-87.0, 0.0).exp_().mul_(legal)
        total = e.sum(dim=-1, keepdim=True)
        lse = total.log().add_(top)
        p = e.div_(total)
        entropy = lse.squeeze(-1) - (p * logits).sum(dim=-1)  # (k,)
        index = actions.long().unsqueeze(-1)
        chosen = th.where(legal.gather(-1, index), logits.gather(-1, index), neg)
        log_prob = (chosen - lse).squeeze(-1)  # (k,)
        ctx.save_for_backward(p, logits, lse, entropy, index, legal.gather(-1, index))
        return log_prob, entropy

    @staticmethod
    def backward(ctx: Any, grad_log_prob: th.Tensor, grad_entropy: th.Tensor) -> tuple[th.Tensor, None, None]:
        p, logits, lse, entropy, index, chosen_legal = ctx.saved_tensors
        # d(entropy)/d logits = -p * (logits - lse + H); d(log_prob)/d logits = onehot(a) - p
        g_ent = grad_entropy.unsqueeze(-1)
        g_lp = grad_log_prob.unsqueeze(-1)
        grad = (logits - lse + entropy.unsqueeze(-1)).mul_(p).mul_(-g_ent).sub_(p * g_lp)
        grad.scatter_add_(-1, index, g_lp * chosen_legal)
        return grad, None, None


def _in_place(activation: type[nn.Module]) -> Any:
    """``activation`` working in place where torch has such a form (ReLU and friends): the actor's activations are
    n_units times the joint MLP's, and their fresh allocations showed in profiles."""
    if activation in (nn.ReLU, nn.ReLU6, nn.ELU, nn.SELU, nn.LeakyReLU, nn.Hardtanh):
        return lambda: activation(inplace=True)
    return activation


def _mlp(width: int, sizes: list[int], activation: type[nn.Module]) -> nn.Sequential:
    """Linear layers ``width -> sizes...``, each followed by ``activation`` (no layers: the identity)."""
    layers: list[nn.Module] = []
    for size in sizes:
        layers += [nn.Linear(width, size), activation()]
        width = size
    return nn.Sequential(*layers)
