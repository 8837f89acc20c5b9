"""wrappers/torch_exp.py: exp and logsumexp equal to torch's bit for bit, on the inputs masking produces."""

import pytest
import torch

from smac_hard_gym.wrappers.torch_exp import exp, logsumexp


def test_exp_equals_torch_on_every_range_and_special_value():
    # through the fast range, the denormal results (-104 to -87.3), the underflow to 0, and the special values
    x = torch.cat([torch.linspace(-130.0, 90.0, 400_001), torch.tensor([-1e8, -104.0, -103.97, -87.34, -87.0,
                                                                         float("-inf"), float("inf"), 0.0, -0.0])])
    ours, theirs = exp(x), torch.exp(x)
    assert torch.equal(ours, theirs)
    assert ((theirs > 0) & (theirs < torch.finfo(torch.float32).tiny)).any()  # denormal results were covered
    nan = torch.tensor([float("nan"), -1e8])
    assert exp(nan)[0].isnan() and exp(nan)[1] == 0


@pytest.mark.parametrize("scale", [1.0, 40.0])  # 40: many legal logits far below the max (denormal exps)
def test_logsumexp_and_its_gradient_equal_torchs_on_masked_logits(scale):
    gen = torch.Generator().manual_seed(int(scale))
    flat = (scale * torch.randn(512, 27 * 36, generator=gen)).requires_grad_(True)
    masks = torch.rand(512, 27 * 36, generator=gen) < 0.4
    masks.view(512, 27, 36)[:, :, 1] = True
    # the (units, batch, actions) view of masked logits that the joint policy normalises
    masked = torch.where(masks, flat, torch.tensor(-1e8)).reshape(512, 27, 36).transpose(0, 1)
    ours, theirs = logsumexp(masked), masked.logsumexp(dim=-1, keepdim=True)
    assert torch.equal(ours, theirs)
    weights = torch.randn(theirs.shape, generator=gen)
    grad_theirs = torch.autograd.grad((theirs * weights).sum(), flat, retain_graph=True)[0]
    grad_ours = torch.autograd.grad((ours * weights).sum(), flat)[0]
    assert torch.equal(grad_ours, grad_theirs)
    assert (grad_ours[~masks] == 0).all()  # nothing flows to the masked logits
