"""The KPN, offset block, E2E ablation and loss (torch): shapes, known answers, gradients."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from thermocal.errors import InvalidInputError  # noqa: E402
from thermocal.nn.loss import kpn_loss, masked_l1  # noqa: E402
from thermocal.nn.model import (  # noqa: E402
    KPN,
    KernelHead,
    ModelConfig,
    OffsetBlock,
    RadianceToTemperature,
    apply_folded_kernels,
    apply_kernels,
    count_macs,
    count_parameters,
    fold_kernel_conv,
    with_formed_kernels,
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


@pytest.mark.parametrize("seed", [0, 1])
def test_the_folded_head_is_eq11_with_the_heads_kernels(seed):
    """KernelHead.kernel_sum (the last 1×1 conv folded into a K×K conv of the frames) gives what
    apply_kernels gives with the kernels the head outputs, and the same gradients."""
    torch.manual_seed(seed)
    n, k, mu = 3, 5, 6
    head = KernelHead(mu, n * k * k).double()
    for p in head.parameters():
        torch.nn.init.normal_(p)
    frames = torch.rand(2, n, 9, 11, dtype=torch.float64, requires_grad=True)
    feats = torch.rand(2, mu, 9, 11, dtype=torch.float64)
    want = apply_kernels(frames, head(feats), k)
    got = head.kernel_sum(frames, feats, k)
    assert got.shape == (2, 1, 9, 11)
    assert torch.allclose(got, want, rtol=1e-12, atol=1e-10)
    g_want = torch.autograd.grad(want.sum(), [frames, *head.parameters()])
    g_got = torch.autograd.grad(got.sum(), [frames, *head.parameters()])
    for a, b in zip(g_want, g_got, strict=True):
        assert torch.allclose(a, b, rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("config", [
    {"n_frames": 7, "mu": 8, "levels": 2, "kernel": 5, "radiance": True, "radial": 2},
    {"n_frames": 1, "mu": 4, "levels": 1, "kernel": 1, "variant": "kpn-no-offset"},
    {"n_frames": 3, "mu": 4, "levels": 0, "kernel": 3, "variant": "e2e"},
])
def test_the_whole_network_folded_is_the_network_with_its_kernels_formed(config):
    """KPN.forward (folded) against with_formed_kernels(KPN) on random weights: the same
    temperatures to float rounding; the copy leaves the model alone, and nn.Module.apply
    still walks every module (the head's method does not shadow it)."""
    cfg = ModelConfig(**config)
    m = KPN(cfg).eval()
    for p in m.parameters():
        torch.nn.init.normal_(p, std=0.2)
    formed = with_formed_kernels(m)
    x = torch.rand(2, cfg.n_frames, 16, 24)
    fpa = torch.rand(2)
    r2 = torch.rand(2, cfg.position_planes, 16, 24) if cfg.radial else None
    with torch.no_grad():
        want, got = formed(x, fpa, r2=r2), m(x, fpa, r2=r2)
    assert torch.allclose(got, want, rtol=1e-5, atol=1e-5)
    assert type(m.head) is KernelHead and type(formed.head) is not KernelHead
    visited = []
    m.apply(visited.append)
    assert m.head in visited and len(visited) == len(list(m.modules()))


def test_the_folded_kernels_check_their_shapes():
    head = KernelHead(4, 2 * 9)
    with pytest.raises(InvalidInputError, match="kernel taps"):
        fold_kernel_conv(head.net[-1].weight, head.net[-1].bias, 3, 3)
    with pytest.raises(InvalidInputError, match="kernel taps"):  # 3 frames, kernels for 2
        head.kernel_sum(torch.rand(1, 3, 8, 8), torch.rand(1, 4, 8, 8), 3)
    folded = fold_kernel_conv(head.net[-1].weight, head.net[-1].bias, 2, 3)
    with pytest.raises(InvalidInputError, match="do not match"):
        apply_folded_kernels(torch.rand(1, 2, 8, 8), torch.rand(1, 4, 8, 9), folded, 3)


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
    # input conv 2→4 (3×3); bottom block 4→4→4→4 (3×3); head 4→4→4 (1×1); eq. 11 folded:
    # a 3×3 conv 2→(4+1) and a 4-channel product
    want = px * (2 * 4 * 9 + 3 * 4 * 4 * 9 + 4 * 4 + 4 * 4) + px * (5 * 2 * 9 + 4)
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


@pytest.mark.parametrize("temp_range_c", [(-40.0, 100.0), (-20.0, 60.0)])
def test_radiance_to_temperature_inverts_the_band_integral(temp_range_c):
    from thermocal.radiometry import band_radiance

    lo, hi = temp_range_c
    layer = RadianceToTemperature(temp_range_c)
    t_c = np.linspace(lo - 30.0, hi + 30.0, 777)
    ends = band_radiance(np.array([lo, hi]) + 273.15)
    x = (band_radiance(t_c + 273.15) - ends[0]) / (ends[1] - ends[0])
    for dtype, tol_c in ((torch.float64, 1e-3), (torch.float32, 2e-3)):
        got = layer(torch.tensor(x, dtype=dtype)).double().numpy() * (hi - lo) + lo
        assert np.abs(got - t_c).max() < tol_c
    # the two directions are inverse; the slope is dT/dL, larger where the scene is cold
    t = torch.linspace(0.0, 1.0, 50, dtype=torch.float64, requires_grad=True)
    assert torch.allclose(layer(layer.radiance(t)), t, atol=1e-9)
    xr = layer.radiance(torch.tensor([0.0, 1.0], dtype=torch.float64)).requires_grad_(True)
    layer(xr).sum().backward()
    assert xr.grad[0] > 1.5 * xr.grad[1] > 0
    with pytest.raises(InvalidInputError):
        RadianceToTemperature((50.0, 10.0))


def _ideal_camera_kpn(radial: int, beta: float):
    """A radiance KPN set by hand for an ideal camera (gain 90 counts per W/(m² sr), offset 2500
    counts, plus ``beta · R²``) seen without parallax, and its input: (model, frames, R², truth)."""
    from thermocal.camera.presets import radial_map
    from thermocal.radiometry import band_radiance

    n, lo, hi, g, o = 3, -40.0, 100.0, 90.0, 2500.0
    m = KPN(ModelConfig(n_frames=n, mu=4, levels=1, kernel=3, radiance=True, radial=radial),
            temp_range_c=(lo, hi))
    r2 = radial_map((16, 24)) ** 2
    truth_c = np.linspace(-30.0, 90.0, 16 * 24).reshape(16, 24)
    counts = g * band_radiance(truth_c + 273.15) + o + beta * r2
    c_min, c_max = 700.0, 14700.0
    frames = torch.tensor((counts - c_min) / (c_max - c_min)).float().expand(1, n, 16, 24)
    # normalised radiance = a · normalised counts + b − (β / g) · R² (normalised)
    ends = band_radiance(np.array([lo, hi]) + 273.15)
    a = (c_max - c_min) / (g * (ends[1] - ends[0]))
    b = ((c_min - o) / g - ends[0]) / (ends[1] - ends[0])
    with torch.no_grad():
        for p in [*m.unet.parameters(), *m.head.parameters()]:
            p.zero_()
        m.head.net[-1].bias.view(n, 9)[:, 4] = a / n
        m.offset.delta.zero_()
        m.offset.delta[:, 0] = b
        if radial:
            m.offset.delta_radial.zero_()
            m.offset.delta_radial[:, 0, 0] = -beta / (g * (ends[1] - ends[0]))
    return m.eval(), frames, torch.tensor(r2)[None, None], truth_c


def _estimate_c(m, frames, r2):
    with torch.no_grad():
        out = m(frames, torch.zeros(1), r2=r2 if m.config.radial else None)
    return out[0, 0].double().numpy() * 140.0 - 40.0


def test_radiance_kpn_is_exact_for_an_ideal_camera():
    """Counts affine in band radiance (an ideal camera) are turned into the exact temperature
    by a radiance KPN whose kernels are a constant gain and whose offset is a constant; in
    temperature no constant gain and offset would do (Planck's curve)."""
    m, frames, r2, truth_c = _ideal_camera_kpn(radial=0, beta=0.0)
    assert np.abs(_estimate_c(m, frames, r2) - truth_c).max() < 0.01
    counts = frames[0, 0].double().numpy().ravel()
    fit = np.polyval(np.polyfit(counts, truth_c.ravel(), 1), counts)
    assert np.abs(fit - truth_c.ravel()).max() > 3.0


def test_offset_block_radial_terms_known_answer():
    blk = OffsetBlock(n_frames=2, degree=1, radial=2)
    with torch.no_grad():
        blk.delta.zero_()
        blk.delta[:, 0] = 0.5  # constant
        blk.delta_radial.zero_()
        blk.delta_radial[:, 0, 0] = -0.2  # · R²
        blk.delta_radial[:, 1, 1] = 0.1  # · t · R⁴  (feature index i·(ν+1) + j: i=0, j=1)
    r2 = torch.rand(3, 1, 4, 5)
    fpa = torch.tensor([0.0, 0.5, 1.0])
    d = blk(torch.rand(3, 2), fpa, r2)
    want = 0.5 - 0.2 * r2 + 0.1 * fpa.view(3, 1, 1, 1) * r2**2
    assert d.shape == (3, 1, 4, 5) and torch.allclose(d, want, atol=1e-6)


def test_radial_model_needs_the_pixels_positions():
    m = KPN(ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, radial=1))
    with pytest.raises(InvalidInputError, match="sensor position"):
        m(torch.rand(1, 3, 8, 8), torch.rand(1))
    with pytest.raises(InvalidInputError, match="sensor position"):
        m(torch.rand(1, 3, 8, 8), torch.rand(1), r2=torch.rand(1, 1, 4, 4))
    assert m(torch.rand(1, 3, 8, 8), torch.rand(1), r2=torch.rand(1, 1, 8, 8)).shape == (
        1, 1, 8, 8)
    with pytest.raises(InvalidInputError):
        ModelConfig(radial=-1)


def test_radial_radiance_kpn_is_exact_for_a_camera_with_a_radial_offset():
    """A hovering camera (no parallax) whose offset falls off radially (Oz eq. 16-17): the
    radial offset block removes it exactly; without its radial terms the corners are off."""
    m, frames, r2, truth_c = _ideal_camera_kpn(radial=1, beta=-100.0)
    assert np.abs(_estimate_c(m, frames, r2) - truth_c).max() < 0.01
    with torch.no_grad():
        m.offset.delta_radial.zero_()
    assert np.abs(_estimate_c(m, frames, r2) - truth_c).max() > 1.0


def test_offset_block_evaluates_each_frame_at_its_own_position():
    """With one R² plane per frame, frame n's radial terms are taken at its own R²; with the
    same plane for every frame it is the pivot-only block."""
    torch.manual_seed(0)
    blk = OffsetBlock(3, degree=1, radial=2)
    with torch.no_grad():
        blk.delta_radial.normal_()
    means, fpa = torch.rand(2, 3), torch.rand(2)
    r2 = torch.rand(2, 1, 4, 5)
    same = blk(means, fpa, r2.expand(2, 3, 4, 5))
    assert torch.allclose(same, blk(means, fpa, r2), atol=1e-6)
    per = torch.rand(2, 3, 4, 5)
    d = blk(means, fpa, per)
    # by hand: the constant part plus mean over n of Σ_k coef_nk · R²_n^(k+1)
    p = torch.arange(2, dtype=torch.float32)
    feats = ((means[..., None] ** p)[..., :, None] * (fpa[:, None] ** p)[:, None, None, :]
             ).flatten(2)
    const = (feats * blk.delta).sum(dim=2).mean(dim=1).view(-1, 1, 1, 1)
    coef = torch.einsum("bnf,nfk->bnk", feats, blk.delta_radial)
    want = const + sum((coef[:, :, k, None, None] * per ** (k + 1)).mean(dim=1, keepdim=True)
                       for k in range(2))
    assert torch.allclose(d, want, atol=1e-5) and not torch.allclose(d, same, atol=1e-3)


def test_radial_frames_model_takes_one_position_plane_per_frame():
    cfg = ModelConfig(n_frames=3, mu=4, levels=1, kernel=3, radial=1, radial_frames=True)
    assert cfg.position_planes == 3 and ModelConfig(radial=1).position_planes == 1
    m = KPN(cfg)
    with pytest.raises(InvalidInputError, match=r"\(1, 3, 8, 8\)"):
        m(torch.rand(1, 3, 8, 8), torch.rand(1), r2=torch.rand(1, 1, 8, 8))
    assert m(torch.rand(1, 3, 8, 8), torch.rand(1), r2=torch.rand(1, 3, 8, 8)).shape == (
        1, 1, 8, 8)
    assert count_macs(m, 8, 8) > 0
    with pytest.raises(InvalidInputError, match="radial"):
        ModelConfig(radial=0, radial_frames=True)
