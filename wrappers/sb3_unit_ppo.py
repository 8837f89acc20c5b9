"""MaskablePPO with MAPPO's policy loss for the unit-shared policy: each unit's probability ratio clipped on its own.

SB3's PPO clips the probability ratio of the whole action. For a joint controller that is the product of the units'
ratios, so a clip of 0.2 on 27 units is a far tighter trust region than MAPPO's, which clips each agent's ratio
(Yu et al. 2022; marlbenchmark/on-policy, ``r_mappo.py``): the clip that suits a map then depends on its unit count,
and the shared policy's joint clip had to be measured map by map (``mappo_settings.py``). :class:`UnitRatioMaskablePPO`
takes MAPPO's loss instead, with every other part of sb3-contrib's MaskablePPO unchanged (rollouts, GAE, the value
loss, one optimiser, ``max_grad_norm``, ``save``/``load``):

- the surrogate is taken per living unit, ``min(r_i A, clip(r_i, 1 - c, 1 + c) A)`` with ``r_i`` unit i's ratio and
  ``A`` the battle-step's advantage, and averaged over the living units of the minibatch (MAPPO's
  ``use_policy_active_masks``): a dead unit, whose only legal action is no-op, takes no part;
- the advantages are normalised over the living units' rows (MAPPO normalises over its active agents);
- the entropy bonus is the mean entropy of a living unit (SB3's is the joint entropy, the sum over the units).

The units' old log-probabilities are not in SB3's rollout buffer (it keeps the joint one); they are computed once per
update, before the first gradient step, from the same policy that collected the rollout, which gives them exactly.
It needs :class:`~smac_hard_gym.wrappers.sb3_shared.SharedUnitPolicy` (its ``evaluate_unit_actions``). A model it
trains is an ordinary MaskablePPO model: ``MaskablePPO.load`` plays it.

>>> from smac_hard_gym.wrappers.sb3_unit_ppo import UnitRatioMaskablePPO
>>> model = UnitRatioMaskablePPO(SharedUnitPolicy, venv, rollout_buffer_class=SharedUnitRolloutBuffer,
...                              policy_kwargs=shared_policy_kwargs(venv), clip_range=0.2)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import numpy as np
import torch as th
import torch.nn.functional as F
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.buffers import MaskableRolloutBufferSamples
from stable_baselines3.common.utils import explained_variance

from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer

__all__ = ["UnitRatioMaskablePPO", "UnitSurrogate", "unit_clipped_surrogate"]


class UnitSurrogate(NamedTuple):
    """MAPPO's clipped surrogate loss over living units, and what is logged with it."""

    loss: th.Tensor  # to minimise: minus the mean over living units of min(r A, clip(r) A)
    clip_fraction: float  # share of living units whose ratio left [1 - clip, 1 + clip]
    approx_kl: float  # mean over living units of (r - 1) - log r


def unit_clipped_surrogate(log_prob: th.Tensor, old_log_prob: th.Tensor, advantages: th.Tensor, living: th.Tensor,
                           clip_range: float, normalize_advantage: bool = True) -> UnitSurrogate:
    """The per-unit clipped surrogate of ``log_prob``/``old_log_prob`` (B, n_units) with one advantage per battle-step
    (B,), counted over the ``living`` (B, n_units) units only; the advantages are first normalised over those rows
    (MAPPO's normalisation) when ``normalize_advantage``."""
    mask = living.to(log_prob.dtype)
    count = mask.sum().clamp(min=1.0)
    adv = advantages.reshape(-1, 1).expand_as(log_prob)
    if normalize_advantage:
        mean = (adv * mask).sum() / count
        std = (((adv - mean) ** 2 * mask).sum() / count).sqrt()
        adv = (adv - mean) / (std + 1e-8)
    log_ratio = log_prob - old_log_prob
    ratio = th.exp(log_ratio)
    surrogate = th.min(adv * ratio, adv * th.clamp(ratio, 1.0 - clip_range, 1.0 + clip_range))
    loss = -(surrogate * mask).sum() / count
    with th.no_grad():
        clipped = ((ratio - 1.0).abs() > clip_range).to(mask.dtype)
        clip_fraction = float((clipped * mask).sum() / count)
        approx_kl = float((((ratio - 1.0) - log_ratio) * mask).sum() / count)
    return UnitSurrogate(loss, clip_fraction, approx_kl)


class UnitRatioMaskablePPO(MaskablePPO):
    """sb3-contrib's MaskablePPO whose policy loss is MAPPO's: per-unit ratios, each clipped, averaged over the
    living units, and the mean entropy of a living unit as the bonus (see the module docstring). Needs a policy with
    ``evaluate_unit_actions`` (:class:`~smac_hard_gym.wrappers.sb3_shared.SharedUnitPolicy`)."""

    def _old_unit_log_probs(self, chunk: int = 4096) -> th.Tensor:
        """Every flattened rollout row's per-unit log-probabilities under the policy that collected it (this
        update has not stepped yet), in the buffer's flattened order."""
        buffer = self.rollout_buffer
        parts = []
        with th.no_grad():
            for start in range(0, len(buffer.observations), chunk):
                rows = slice(start, start + chunk)
                _, log_prob, _, _ = self.policy.evaluate_unit_actions(
                    buffer.to_torch(buffer.observations[rows]), buffer.to_torch(buffer.actions[rows]),
                    action_masks=buffer.to_torch(buffer.action_masks[rows].reshape(-1, buffer.mask_dims)))
                parts.append(log_prob)
        return th.cat(parts)

    def _minibatches(self, old_unit_log_prob: th.Tensor) -> Iterator[tuple[MaskableRolloutBufferSamples, th.Tensor]]:
        """The update's minibatches, each with its rows' old per-unit log-probabilities."""
        buffer = self.rollout_buffer
        total = buffer.buffer_size * buffer.n_envs
        if self.batch_size is None or self.batch_size >= total:  # the whole rollout, in the buffer's order
            whole = next(buffer.get(None)) if isinstance(buffer, MaskableJointRolloutBuffer) \
                else buffer._get_samples(np.arange(total))  # SB3's get() would shuffle it
            yield whole, old_unit_log_prob
            return
        indices = np.random.permutation(total)
        for start in range(0, total, self.batch_size):
            rows = indices[start:start + self.batch_size]
            yield buffer._get_samples(rows), old_unit_log_prob[th.as_tensor(rows)]

    def train(self) -> None:
        """One PPO update on the rollout buffer with MAPPO's per-unit policy loss (the rest as MaskablePPO's)."""
        if not hasattr(self.policy, "evaluate_unit_actions"):
            raise TypeError(f"UnitRatioMaskablePPO needs a policy with per-unit log-probabilities (SharedUnitPolicy), "
                            f"got {type(self.policy).__name__}")
        self.policy.set_training_mode(True)
        self._update_learning_rate(self.policy.optimizer)
        clip_range = self.clip_range(self._current_progress_remaining)  # type: ignore[operator]
        clip_range_vf = None if self.clip_range_vf is None else \
            self.clip_range_vf(self._current_progress_remaining)  # type: ignore[operator]
        next(self.rollout_buffer.get(None))  # SB3 flattens the rollout on its first get()
        old_unit_log_prob = self._old_unit_log_probs()
        entropy_losses, pg_losses, value_losses, clip_fractions = [], [], [], []
        approx_kl_divs: list[float] = []
        continue_training = True
        for _ in range(self.n_epochs):
            approx_kl_divs = []
            for data, old_log_prob in self._minibatches(old_unit_log_prob):
                values, log_prob, entropy, living = self.policy.evaluate_unit_actions(
                    data.observations, data.actions, action_masks=data.action_masks)
                values = values.flatten()
                surrogate = unit_clipped_surrogate(log_prob, old_log_prob, data.advantages, living, clip_range,
                                                   self.normalize_advantage)
                pg_losses.append(surrogate.loss.item())
                clip_fractions.append(surrogate.clip_fraction)
                approx_kl_divs.append(surrogate.approx_kl)
                values_pred = values if clip_range_vf is None else data.old_values + th.clamp(
                    values - data.old_values, -clip_range_vf, clip_range_vf)
                value_loss = F.mse_loss(data.returns, values_pred)
                value_losses.append(value_loss.item())
                mask = living.to(entropy.dtype)
                entropy_loss = -(entropy * mask).sum() / mask.sum().clamp(min=1.0)
                entropy_losses.append(entropy_loss.item())
                loss = surrogate.loss + self.ent_coef * entropy_loss + self.vf_coef * value_loss
                if self.target_kl is not None and surrogate.approx_kl > 1.5 * self.target_kl:
                    continue_training = False
                    break
                self.policy.optimizer.zero_grad()
                loss.backward()
                th.nn.utils.clip_grad_norm_(self.policy.parameters(), self.max_grad_norm)
                self.policy.optimizer.step()
            self._n_updates += 1
            if not continue_training:
                break
        buffer = self.rollout_buffer
        self.logger.record("train/entropy_loss", np.mean(entropy_losses))
        self.logger.record("train/policy_gradient_loss", np.mean(pg_losses))
        self.logger.record("train/value_loss", np.mean(value_losses))
        self.logger.record("train/approx_kl", np.mean(approx_kl_divs) if approx_kl_divs else 0.0)
        self.logger.record("train/clip_fraction", np.mean(clip_fractions))
        self.logger.record("train/explained_variance",
                           explained_variance(buffer.values.flatten(), buffer.returns.flatten()))
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/clip_range", clip_range)
        if clip_range_vf is not None:
            self.logger.record("train/clip_range_vf", clip_range_vf)
