"""MaskablePPO rollout buffers that hand each minibatch to torch without copying it a second time.

SB3's buffers gather a minibatch with fancy indexing (``observations[batch_inds]``, a new array) and then pass it to
``th.tensor``, which copies it again. On the large maps the joint observation has 7-8k features, so that second
copy of every minibatch is about 5% of a run. These buffers wrap the gathered arrays instead (``th.as_tensor``):
every array their ``_get_samples`` converts is a fresh one, never a view of the buffer, so nothing aliases the
stored rollout and the samples are the same tensors.

>>> from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer
>>> model = MaskablePPO(policy, venv, rollout_buffer_class=MaskableJointRolloutBuffer)  # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
import torch as th
from sb3_contrib.common.maskable.buffers import MaskableDictRolloutBuffer, MaskableRolloutBuffer

__all__ = ["MaskableJointDictRolloutBuffer", "MaskableJointRolloutBuffer"]


class _WrapGatheredArrays:
    def to_torch(self, array: np.ndarray, copy: bool = False) -> th.Tensor:
        # only _get_samples calls this, always with an array it has just gathered (fancy index, flatten, reshape)
        return th.tensor(array, device=self.device) if copy else th.as_tensor(array, device=self.device)


class MaskableJointRolloutBuffer(_WrapGatheredArrays, MaskableRolloutBuffer):
    """sb3-contrib's ``MaskableRolloutBuffer`` whose minibatches are the gathered arrays, not copies of them."""


class MaskableJointDictRolloutBuffer(_WrapGatheredArrays, MaskableDictRolloutBuffer):
    """sb3-contrib's ``MaskableDictRolloutBuffer`` whose minibatches are the gathered arrays, not copies of them."""
