"""MaskablePPO rollout buffers that hand each minibatch to torch without copying it a second time.

SB3's buffers gather a minibatch with fancy indexing (``observations[batch_inds]``, a new array) and then pass it to
``th.tensor``, which copies it again. On the large maps the joint observation has 7-8k features, so that second
copy of every minibatch is about 5% of a run. These buffers wrap the gathered arrays instead (``th.as_tensor``):
every array their ``_get_samples`` converts is a fresh one, never a view of the buffer, so nothing aliases the
stored rollout and the samples are the same tensors.

When one minibatch is the whole rollout (``batch_size`` None or at least ``n_steps * n_envs``, as the shared
policy's MAPPO settings train), :class:`MaskableJointRolloutBuffer` skips the shuffle: SB3 would gather the whole
rollout in a new random order for every epoch (on 27m_vs_30m with 4 frames, 3,200 x 31k floats, 15 times an update:
about 40% of the update), although one minibatch of every sample gives the same loss in any order. It wraps the
flattened rollout once and hands the same samples to every epoch of the update. The losses are the same sums in
another order, so the weights agree with SB3's buffer to float rounding, not bit for bit.

>>> from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer
>>> model = MaskablePPO(policy, venv, rollout_buffer_class=MaskableJointRolloutBuffer)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Generator

import numpy as np
import torch as th
from sb3_contrib.common.maskable.buffers import (
    MaskableDictRolloutBuffer,
    MaskableRolloutBuffer,
    MaskableRolloutBufferSamples,
)

__all__ = ["MaskableJointDictRolloutBuffer", "MaskableJointRolloutBuffer"]


class _WrapGatheredArrays:
    def to_torch(self, array: np.ndarray, copy: bool = False) -> th.Tensor:
        # only _get_samples calls this, always with an array it has just gathered (fancy index, flatten, reshape)
        return th.tensor(array, device=self.device) if copy else th.as_tensor(array, device=self.device)


class MaskableJointRolloutBuffer(_WrapGatheredArrays, MaskableRolloutBuffer):
    """sb3-contrib's ``MaskableRolloutBuffer`` whose minibatches are the gathered arrays, not copies of them, and
    whose one whole-rollout minibatch is built once per update, in the rollout's order (see the module docstring)."""

    # the arrays SB3's get() flattens from (n_steps, n_envs, ...) to (n_steps * n_envs, ...)
    _FLATTENED = ("observations", "actions", "values", "log_probs", "advantages", "returns", "action_masks")

    def reset(self) -> None:
        super().reset()
        self._whole: MaskableRolloutBufferSamples | None = None  # the whole-rollout minibatch of this rollout

    def get(self, batch_size: int | None = None) -> Generator[MaskableRolloutBufferSamples, None, None]:
        total = self.buffer_size * self.n_envs
        if batch_size is not None and batch_size < total:
            yield from super().get(batch_size)
            return
        if self._whole is None:
            assert self.full, "the rollout is not complete"
            if not self.generator_ready:
                for name in self._FLATTENED:
                    self.__dict__[name] = self.swap_and_flatten(self.__dict__[name])
                self.generator_ready = True
            # views of the flattened arrays (nothing in an update writes to its samples; reset() drops them)
            self._whole = MaskableRolloutBufferSamples(*map(self.to_torch, (
                self.observations, self.actions, self.values.reshape(-1), self.log_probs.reshape(-1),
                self.advantages.reshape(-1), self.returns.reshape(-1), self.action_masks.reshape(-1, self.mask_dims))))
        yield self._whole


class MaskableJointDictRolloutBuffer(_WrapGatheredArrays, MaskableDictRolloutBuffer):
    """sb3-contrib's ``MaskableDictRolloutBuffer`` whose minibatches are the gathered arrays, not copies of them."""
