"""The KPN, offset block, E2E ablation and loss (torch): shapes, known answers, gradients."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from thermocal.errors import InvalidInputError  # noqa: E402
from thermocal.nn.loss import kpn_loss, masked_l1  # noqa: E402
from thermocal.nn.model import (  # noqa: E402
    KPN,
    ModelConfig,
    OffsetBlock,
    apply_kernels,
    count_macs,
    count_parameters,
)


@pytest.fixture(autouse=True)
def _seed():
    torch.manual_seed(0)


@pytest.mark.parametrize("variant", ["kpn", "kpn-no-offset", "e2e"])
@pytest.mark.parametrize("fpa_input", [False, True])
def test_shapes(variant, fpa_input):
    m = KPN(ModelConfig(n_frames=5, mu=8, levels=2, kernel=3, variant=variant,
                        fpa_input=fpa_input))
    out = m(torch.rand(2, 5, 32, 48), torch.rand(2))
    assert out.shape == (2, 1, 32, 48)
    assert torch.isfinite(out).all()


def test_paper_configuration_is_constructible():
    cfg = ModelConfig(n_frames=7, mu=64, xi=2, levels=4, kernel=5)
    m = KPN(cfg, init=False)  # the orthogonal init of 69 M parameters takes half a minute
    assert cfg.multiple == 16
    # encoder channels mu·xi^(i+1) (Table I), kernel head N·K² channels (Table II)
    assert [blk[-1].out_channels for blk in m.unet.enc] == [128, 256, 512, 1024]
    assert m.head.net[-1].out_channels == 7 * 25
    assert m.offset.delta.shape == (7, 25)
    assert count_parameters(m) > 10_000_000


def test_bad_input():
    m = KPN(ModelConfig(n_frames=3, mu=4, levels=2, kernel=3))
    with pytest.raises(InvalidInputError, match=r"\(B, 3, H, W\)"):
        m(torch.rand(1, 4, 16, 16), torch.rand(1))
    with pytest.raises(InvalidInputError, match="multiples of 4"):
        m(torch.rand(1, 3, 18, 16), torch.rand(1))
    with pytest.raises(InvalidInputError):
        ModelConfig(kernel=4)
    with pytest.raises(InvalidInputError):
        ModelConfig(variant="nope")


def test_apply_kernels_known_answer():
    """A kernel with a single 1 at tap (dy, dx) shifts the frame; summing frames adds them."""
    frames = torch.arange(2 * 6 * 7, dtype=torch.float32).view(1, 2, 6, 7)
    k = 3
    kernels = torch.zeros(1, 2 * k * k, 6, 7)
    kernels[:, 4] = 1.0  # frame 0, centre tap
    kernels[:, k * k + 5] = 2.0  # frame 1, tap (row 1, col 2): the right neighbour
    out = apply_kernels(frames, kernels, k)[0, 0]
    right = torch.zeros(6, 7)
    right[:, :-1] = frames[0, 1, :, 1:]
    assert torch.allclose(out, frames[0, 0] + 2.0 * right)


def test_untrained_kpn_is_the_mean_of_the_frames():
    """The centre-tap bias makes the untrained KPN (no offset) average the registered frames."""
    m = KPN(ModelConfig(n_frames=3, mu=8, levels=1, kernel=3, variant="kpn-no-offset"))
    for p in m.parameters():
        if p.dim() > 1:
            torch.nn.init.zeros_(p)
    m.eval()
    x = torch.rand(1, 3, 8, 8)
    assert torch.allclose(m(x, torch.zeros(1)), x.mean(dim=1, keepdim=True), atol=1e-6)


def test_offset_block_is_eq10():
    blk = OffsetBlock(2, 2)
    with torch.no_grad():
        blk.delta.copy_(torch.arange(18, dtype=torch.float32).view(2, 9))
    means = torch.tensor([[0.3, 0.6]])
    t = torch.tensor([0.5])
    want = 0.0
    for n in range(2):
        for i in range(3):
            for j in range(3):
                want += float(blk.delta.detach()[n, i * 3 + j]) * float(means[0, n]) ** i * 0.5**j
    assert float(blk(means, t).detach()) == pytest.approx(want / 2, rel=1e-5)


def test_gradcheck_offset_and_kernels():
    blk = OffsetBlock(2, 2).double()
    with torch.no_grad():
        blk.delta.normal_()
    means = torch.rand(1, 2, dtype=torch.float64, requires_grad=True)
    t = torch.rand(1, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda a, b: blk(a, b), (means, t))
    frames = torch.rand(1, 2, 5, 5, dtype=torch.float64, requires_grad=True)
    kern = torch.rand(1, 18, 5, 5, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda f, k: apply_kernels(f, k, 3), (frames, kern))


def test_loss_masks_and_zero_at_truth():
    y = torch.rand(2, 1, 16, 16)
    mask = torch.zeros(2, 1, 16, 16, dtype=torch.bool)
    mask[..., 4:12, 4:12] = True
    assert float(kpn_loss(y, y, mask)) == pytest.approx(0.0, abs=1e-6)
    est = y.clone()
    est[..., :2, :] += 5.0  # outside the mask: the L1 term does not see it
    assert float(masked_l1(est, y, mask)) == pytest.approx(0.0, abs=1e-7)
    est2 = y + 0.1
    assert float(kpn_loss(est2, y, mask)) == pytest.approx(0.1, rel=0.05)


def test_overfit_one_batch():
    """20 Adam steps on one tiny batch reduce the eq. 12 loss clearly."""
    torch.manual_seed(42)
    m = KPN(ModelConfig(n_frames=3, mu=8, levels=1, kernel=3))
    x = torch.rand(2, 3, 16, 16)
    target = (0.5 * x.mean(dim=1, keepdim=True) + 0.2)
    mask = torch.ones_like(target, dtype=torch.bool)
    fpa = torch.rand(2)
    opt = torch.optim.Adam(m.parameters(), lr=1e-2)
    losses = []
    for _ in range(20):
        opt.zero_grad()
        loss = kpn_loss(m(x, fpa), target, mask)
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    assert losses[-1] < 0.5 * losses[0]


def test_count_macs_matches_a_hand_count():
    cfg = ModelConfig(n_frames=2, mu=4, levels=0, kernel=3, variant="kpn-no-offset")
    m = KPN(cfg)
    h, w = 8, 8
    px = h * w
    # input conv 2→4 (3×3); bottom block 4→4→4→4 (3×3); head 4→4→4→(2·9) (1×1); eq. 11
    want = px * (2 * 4 * 9 + 3 * 4 * 4 * 9 + 4 * 4 + 4 * 4 + 4 * 18) + 2 * 9 * px
    assert count_macs(m, h, w) == want
    assert np.isfinite(count_parameters(m))


def test_centred_kpn_starts_from_the_mean_and_ignores_invalid_pixels():
    m = KPN(ModelConfig(n_frames=3, mu=8, levels=1, kernel=3, centre=True, fpa_input=True))
    for p in m.unet.parameters():
        if p.dim() > 1:
            torch.nn.init.zeros_(p)
    for p in m.head.parameters():
        if p.dim() > 1:
            torch.nn.init.zeros_(p)
    m.eval()
    m.requires_grad_(False)
    x = torch.rand(1, 3, 8, 8)
    valid = torch.ones_like(x, dtype=torch.bool)
    out = m(x, torch.zeros(1), valid)
    assert torch.allclose(out, x.mean(dim=1, keepdim=True), atol=1e-5)
    # a pixel that a frame does not see (0, invalid) does not pull the estimate down
    x2, v2 = x.clone(), valid.clone()
    x2[0, 0, 2, 2], v2[0, 0, 2, 2] = 0.0, False
    out2 = m(x2, torch.zeros(1), v2)
    vf = v2.float()
    level = float(((x2 * vf).sum(dim=(2, 3)) / vf.sum(dim=(2, 3))).mean())
    want = (float(x2[0, 1, 2, 2]) + float(x2[0, 2, 2, 2]) - 2 * level) / 3 + level
    assert float(out2[0, 0, 2, 2]) == pytest.approx(want, abs=1e-5)
    with pytest.raises(InvalidInputError):
        ModelConfig(variant="e2e", centre=True)
