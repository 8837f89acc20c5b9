"""MaskablePPO policies whose joint action (one sub-action per unit, all of the same size) is one batched categorical.

sb3-contrib's ``MaskableMultiCategoricalDistribution`` builds one ``MaskableCategorical`` per unit on every forward
pass, and each of those normalises its logits twice (once when built, once when masked). Every unit of a SMAC map
has the same number of actions, so :class:`BatchedMaskableMultiCategorical` keeps the logits as one (units, batch,
actions) tensor and builds one categorical over it. It lays the rows out as sb3-contrib's per-unit distributions are
laid out, one unit after another, so the same seed samples the same actions and trains the same weights (checked by
``tests/test_sb3.py``). Measured on 2 cores: ``smac-hard-gym train`` (minibatches of 512) on 10m_vs_11m, 32k steps,
11.0-11.9 s of training before, 10.1-10.4 s after; on 8m 5.6 s before, 4.7 s after; with minibatches of 256 and 8
envs 1.8x less CPU on 10m_vs_11m, MMM2 and 27m_vs_30m (the per-unit overhead is per call, not per sample).

>>> from sb3_contrib import MaskablePPO
>>> from smac_hard_gym.wrappers.sb3_policy import MaskableJointPolicy
>>> model = MaskablePPO(MaskableJointPolicy, venv)  # doctest: +SKIP

``smac-hard-gym train`` uses these policies; a model saved with them needs this package to load (as the env does).
"""

from __future__ import annotations

from typing import Any

import torch as th
from sb3_contrib.common.maskable.distributions import MaskableCategorical, MaskableMultiCategoricalDistribution
from sb3_contrib.common.maskable.policies import MaskableActorCriticPolicy, MaskableMultiInputActorCriticPolicy
from torch.distributions import Categorical

__all__ = ["BatchedMaskableMultiCategorical", "MaskableJointPolicy", "MaskableJointMultiInputPolicy"]


class BatchedMaskableMultiCategorical(MaskableMultiCategoricalDistribution):
    """A masked MultiCategorical whose sub-actions all have ``action_dims[0]`` choices, as one categorical over a
    (sub-actions, batch, choices) view of the logits. Same interface and results as the parent."""

    def __init__(self, action_dims: list[int]) -> None:
        if len(set(action_dims)) != 1:
            raise ValueError(f"action_dims must all be equal for a batched categorical, got {list(action_dims)}")
        super().__init__(action_dims)
        self.n_dims, self.n_choices = len(action_dims), int(action_dims[0])
        self._logits: th.Tensor | None = None
        self._distribution: MaskableCategorical | None = None

    def _by_dimension(self, flat: th.Tensor) -> th.Tensor:
        # (batch, dims * choices), or flat -> (dims, batch, choices): each dimension's (batch, choices) slice has the
        # strides of the parent's th.split column block, and rows run dimension after dimension as its distributions
        return flat.reshape(-1, self.n_dims, self.n_choices).transpose(0, 1)

    def proba_distribution(self, action_logits: th.Tensor) -> BatchedMaskableMultiCategorical:
        # built on first use: when masks come first, apply_masking builds it without an unmasked pass
        self._logits, self._distribution = self._by_dimension(action_logits), None
        return self

    @property
    def distribution(self) -> MaskableCategorical:
        if self._distribution is None:
            assert self._logits is not None, "Must set distribution parameters"
            self._distribution = MaskableCategorical(logits=self._logits)
        return self._distribution

    @property
    def distributions(self) -> list[MaskableCategorical]:  # type: ignore[override]
        # the parent's attribute, read by its "parameters set" checks
        return [] if self._logits is None else [self.distribution]

    @distributions.setter
    def distributions(self, value: list[MaskableCategorical]) -> None:
        if value:
            raise AttributeError("set the parameters with proba_distribution()")

    def _joint(self, per_dimension: th.Tensor) -> th.Tensor:
        # (dims, batch) -> the sum over dimensions, in the parent's memory layout and so in its order of summation
        return per_dimension.t().contiguous().sum(dim=1)

    def log_prob(self, actions: th.Tensor) -> th.Tensor:
        return self._joint(self.distribution.log_prob(actions.view(-1, self.n_dims).t()))

    def entropy(self) -> th.Tensor:
        return self._joint(self.distribution.entropy())

    def sample(self) -> th.Tensor:
        return self.distribution.sample().t()

    def mode(self) -> th.Tensor:
        return th.argmax(self.distribution.probs, dim=-1).t()

    def apply_masking(self, masks: Any) -> None:
        if masks is not None:
            masks = self._by_dimension(th.as_tensor(masks, dtype=th.bool))
        if self._distribution is None and masks is not None:
            assert self._logits is not None, "Must set distribution parameters"
            self._distribution = _masked_categorical(self._logits, masks)
        else:
            self.distribution.apply_masking(masks)


def _masked_categorical(logits: th.Tensor, masks: th.Tensor) -> MaskableCategorical:
    """``MaskableCategorical(logits=logits)`` then ``.apply_masking(masks)``, less the constructor's unmasked pass.

    The constructor normalises the logits, keeps them, then re-applies "no mask", normalising them a second time;
    masking discards that second result and starts again from the kept ones. Skipping it leaves every tensor as it
    was (same operations on the same inputs) and saves a third of the log-sum-exps, which are exp-bound.
    """
    distribution = MaskableCategorical.__new__(MaskableCategorical)
    distribution.masks = None
    Categorical.__init__(distribution, None, logits, None)  # what MaskableCategorical.__init__ passes
    distribution._original_logits = distribution.logits
    distribution.apply_masking(masks)
    return distribution


class _BatchedJointAction:
    """Swaps sb3-contrib's MultiCategorical for the batched one when every sub-action has the same size."""

    def _build(self, lr_schedule: Any) -> None:
        dims = getattr(self.action_dist, "action_dims", None)
        if type(self.action_dist) is MaskableMultiCategoricalDistribution and len(set(dims)) == 1:
            self.action_dist = BatchedMaskableMultiCategorical(list(dims))
        super()._build(lr_schedule)


class MaskableJointPolicy(_BatchedJointAction, MaskableActorCriticPolicy):
    """``MaskableActorCriticPolicy`` (MaskablePPO's ``"MlpPolicy"``) with the batched joint action."""


class MaskableJointMultiInputPolicy(_BatchedJointAction, MaskableMultiInputActorCriticPolicy):
    """``MaskableMultiInputActorCriticPolicy`` (``"MultiInputPolicy"``, dict observations) with the batched joint
    action."""
