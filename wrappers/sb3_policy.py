"""MaskablePPO policies whose joint action (one sub-action per unit, all of the same size) is one batched categorical.

sb3-contrib's ``MaskableMultiCategoricalDistribution`` builds one ``MaskableCategorical`` per unit on every forward
pass, and each of those normalises its logits twice (once when built, once when masked). Every unit of a SMAC map
has the same number of actions, so :class:`BatchedMaskableMultiCategorical` keeps the logits as one (units, batch,
actions) tensor and builds one categorical over it. It lays the rows out as sb3-contrib's per-unit distributions are
laid out, one unit after another, so the same seed samples the same actions and trains the same weights (checked by
``tests/test_sb3.py``). Measured on 2 cores: ``smac-hard-gym train`` (minibatches of 512) on 10m_vs_11m, 32k
steps, 11.0-11.9 s of training before, 10.1-10.4 s after; on 8m 5.6 s before, 4.7 s after; with minibatches of 256
and 8 envs 1.8x less CPU on 10m_vs_11m, MMM2 and 27m_vs_30m (the per-unit overhead is per call, not per sample).

The categorical skips sb3-contrib's discarded unmasked normalisation and normalises with :mod:`torch_exp`'s
logsumexp where the logits are masked, torch's bit for bit without torch's slow exp on the -1e8s. With the joint
layout and the no-copy buffers of ``sb3_buffers``, ``smac-hard-gym bench train`` measures 1.22x (8m), 1.33x
(10m_vs_11m) and 1.31x (27m_vs_30m) the training steps/s of sb3-contrib's policy and buffer, with equal weights.

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
from torch.distributions import Distribution

from smac_hard_gym.smac.frame_stack import check_frame_stack
from smac_hard_gym.wrappers.torch_exp import logsumexp

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
            self._distribution = _JointCategorical(self._logits)
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
            self._distribution = _JointCategorical(self._logits, masks)
        else:
            self.distribution.apply_masking(masks)


class _JointCategorical(MaskableCategorical):
    """sb3-contrib's ``MaskableCategorical`` (logits only) normalising with :func:`torch_exp.logsumexp`: the same
    tensors, without torch's slow exp on the masked logits.

    ``_JointCategorical(logits, masks)`` is ``MaskableCategorical(logits=logits)`` then ``.apply_masking(masks)``,
    less the constructor's pass that re-applies "no mask": it normalises the normalised logits a second time, and
    masking discards that and starts again from the first, so skipping it leaves every tensor as it was.
    """

    def __init__(self, logits: th.Tensor, masks: th.Tensor | None = None) -> None:
        self.masks = None
        self._normalise(logits, masked=False)
        self._original_logits = self.logits
        self.apply_masking(masks)

    def _normalise(self, logits: th.Tensor, masked: bool) -> None:
        # Categorical.__init__(logits=logits), with the logsumexp swapped where masked logits would make it slow
        self.__dict__.pop("probs", None)  # a cached lazy property of the previous logits
        slow_path = masked and logits.device.type == "cpu"  # the slow exp is torch's vectorised CPU one
        self.logits = logits - (logsumexp(logits) if slow_path else logits.logsumexp(dim=-1, keepdim=True))
        self._param = self.logits
        self._num_events = logits.size(-1)
        Distribution.__init__(self, logits.size()[:-1], validate_args=getattr(self, "_validate_args", None))

    def apply_masking(self, masks: Any) -> None:
        # as MaskableCategorical.apply_masking: illegal actions' logits become -1e8, None restores the originals
        if masks is None:
            self.masks, logits = None, self._original_logits
        else:
            device, dtype = self._original_logits.device, self._original_logits.dtype
            self.masks = th.as_tensor(masks, dtype=th.bool, device=device).reshape(self._original_logits.shape)
            logits = th.where(self.masks, self._original_logits, th.tensor(-1e8, dtype=dtype, device=device))
        self._normalise(logits, masked=self.masks is not None)


class _BatchedJointAction:
    """Swaps sb3-contrib's MultiCategorical for the batched one when every sub-action has the same size, and records
    ``frame_stack``, the env option the observations come from (saved with the model, so opponents and evaluations
    rebuild the same observation)."""

    def __init__(self, *args: Any, frame_stack: int = 1, **kwargs: Any) -> None:
        self.frame_stack = check_frame_stack(frame_stack)
        super().__init__(*args, **kwargs)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data["frame_stack"] = self.frame_stack
        return data

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
