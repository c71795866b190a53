"""DeepIR: burst NUC with an untrained-network scene prior (Saragadam et al. 2021).

Saragadam, Dave, Veeraraghavan, Baraniuk, "Thermal Image Processing via Physics-Inspired Deep
Networks", ICCV 2021 workshops (arXiv:2108.07973); reference code github.com/vishwa91/DeepIR.

A burst of a jittering camera is factored into a scene that moves and a sensor pattern that does
not::

    y_k = g ⊙ W_k(x) + o + noise,      x = f_θ(z)

with ``g``, ``o`` the per-detector gain and offset (fixed over the burst), ``W_k`` the view of
frame ``k`` into the scene (from the homographies, optionally refined) and ``x`` the output of a
deep-image-prior network ``f_θ`` (a skip encoder-decoder with a sigmoid output, fed fixed noise
``z``; untrained, its structure is the prior). θ, ``g``, ``o`` (and the motion) are fitted
jointly by Adam on::

    L = mean_valid |g ⊙ W_k(x) + o − y_k|  +  λ_x TV₁(x)  +  λ_o TV₂(o)  +  λ_g mean (g − 1)²

(L1 data term on the pixels whose view lies inside the scene canvas; anisotropic L1 total
variation on the scene, λ_x = 0.1/N as the reference code scales it; squared-gradient smoothness
on the offset; an optional pull of the gain to 1). The corrected frames are ``(y_k − o)/g`` of the
iterate with the lowest loss.

Written by hand on torch: no maintained library implements DeepIR (the authors' code is a
research script that needs CUDA and kornia and fixes the network at 5 scales × 128 channels).
Here the network is scaled down (default 4 scales × 16 channels) so that 11 frames at 160×128
take well under a minute on two CPU cores; the scene lives on a canvas that covers every view
(not only the pivot frame), so that every detector is fitted.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError
from thermocal.nuc._common import GAIN_RANGE, as_nuc_frames, check_int, check_positive

__all__ = ["deepir"]

# Largest margin of the scene canvas around the pivot frame, as a fraction of its size: views
# beyond it (a long walk) count as invalid pixels instead of growing the network's input.
_MAX_MARGIN = 0.5


def _check_weight(value: Any, name: str) -> float:
    """A finite float ≥ 0, else :class:`InvalidInputError`."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v < 0:
        raise InvalidInputError(f"{name}: expected a finite value >= 0, got {value!r}")
    return v


def _canvas(hs: np.ndarray, hh: int, w: int) -> tuple[float, float, int, int]:
    """Origin ``(x0, y0)`` and size ``(Hc, Wc)`` of the pivot-frame canvas covering the views."""
    corners = np.array([[0, 0, 1], [w - 1, 0, 1], [w - 1, hh - 1, 1], [0, hh - 1, 1]], float)
    p = np.einsum("nij,cj->nci", hs, corners)
    xy = p[..., :2] / p[..., 2:3]
    mx, my = _MAX_MARGIN * w, _MAX_MARGIN * hh
    x0 = np.floor(np.clip(xy[..., 0].min(), -mx, 0.0))
    y0 = np.floor(np.clip(xy[..., 1].min(), -my, 0.0))
    x1 = np.ceil(np.clip(xy[..., 0].max(), w - 1.0, w - 1.0 + mx))
    y1 = np.ceil(np.clip(xy[..., 1].max(), hh - 1.0, hh - 1.0 + my))
    return float(x0), float(y0), int(y1 - y0) + 1, int(x1 - x0) + 1


def _skip_net(torch: Any, in_ch: int, ch: int, skip_ch: int, scales: int) -> Any:
    """Deep-image-prior "skip" network (Ulyanov et al. 2018, as DeepIR uses it), 1 channel out.

    Each level: a 1×1 skip branch at its resolution; a stride-2 3×3 conv, a 3×3 conv, the deeper
    levels, bilinear upsampling back; concatenation, 3×3 and 1×1 convs. BatchNorm and LeakyReLU
    throughout, reflection padding, sigmoid output.
    """
    nn = torch.nn

    def block(cin: int, cout: int, k: int, stride: int = 1) -> list:
        return [nn.Conv2d(cin, cout, k, stride, padding=k // 2, padding_mode="reflect"),
                nn.BatchNorm2d(cout), nn.LeakyReLU(0.2)]

    class Level(nn.Module):
        def __init__(self, cin: int, deeper: Any) -> None:
            super().__init__()
            self.skip = nn.Sequential(*block(cin, skip_ch, 1))
            self.down = nn.Sequential(*block(cin, ch, 3, 2), *block(ch, ch, 3))
            self.deeper = deeper
            self.up = nn.Sequential(nn.BatchNorm2d(ch + skip_ch), *block(ch + skip_ch, ch, 3),
                                    *block(ch, ch, 1))

        def forward(self, z: Any) -> Any:
            d = self.down(z)
            if self.deeper is not None:
                d = self.deeper(d)
            d = nn.functional.interpolate(d, size=z.shape[-2:], mode="bilinear",
                                          align_corners=False)
            return self.up(torch.cat([self.skip(z), d], 1))

    net = None
    for level in range(scales - 1, -1, -1):
        net = Level(in_ch if level == 0 else ch, net)
    return nn.Sequential(net, nn.Conv2d(ch, 1, 1), nn.Sigmoid())


def deepir(
    frames: Any,
    *,
    homographies: Any = None,
    iterations: int = 600,
    seed: int = 0,
    refine_motion: bool = True,
    channels: int = 16,
    scales: int = 4,
    learning_rate: float = 0.01,
    motion_learning_rate: float = 1e-3,
    scene_tv: float | None = None,
    offset_smoothness: float = 100.0,
    gain_prior: float = 0.0,
    device: str = "auto",
) -> np.ndarray:
    """Burst NUC by DeepIR (Saragadam et al. 2021): scene as an untrained network, joint fit.

    Parameters
    ----------
    frames : array_like, shape (N, H, W)
        Raw frames (counts) of a moving scene, N ≥ 2. Never modified.
    homographies : array_like, shape (N, 3, 3), optional
        Frame → pivot homographies (pixels); when None they are estimated with
        :func:`thermocal.registration.register_burst` (which may raise
        :class:`~thermocal.errors.RegistrationError`).
    iterations : int
        Adam steps (default 600; the paper runs 500–1000 with a larger network). The run time
        is linear in it: about 0.05 s a step for 11 frames at 160×128 on one idle core.
    seed : int
        Seed of the network's weights and input noise; the same seed (and torch thread count:
        the sums' order changes with it) gives the same output. The caller's torch random state
        is left as it was.
    refine_motion : bool
        Also fit a small affine correction to each frame's view (pixels), as the paper does.
    channels, scales : int
        Width and depth of the network (default 16 and 4; the paper: 128 and 5); ``scales`` is
        reduced so that the coarsest level keeps at least 2 pixels.
    learning_rate, motion_learning_rate : float
        Adam step of the network, gain and offset (frames normalised to about [0.1, 0.9]) and of
        the motion correction (pixels).
    scene_tv : float, optional
        Weight λ_x of the scene's L1 total variation; default ``0.1 / N`` (the reference code).
    offset_smoothness : float
        Weight λ_o of the offset's squared gradients (default 100; the reference code's 10 is
        for frames scaled by the scene's range, ours are scaled by the raw frames' 1–99 %
        range, which the fixed pattern widens; 100–1000 measured best on simulated Tau2
        walks, 10 left a third more error).
    gain_prior : float
        Weight λ_g of ``mean (g − 1)²`` (default 0: the paper only starts the gain at 1).
    device : str
        Where torch runs the optimisation: ``"auto"`` (a CUDA GPU when torch sees one, else
        the CPU), ``"cpu"`` or ``"cuda"``. The starting weights and noise are drawn on the CPU
        either way; a GPU's sums run in another order, so its output differs from the CPU's
        in the last digits.

    Returns
    -------
    numpy.ndarray, float32, shape (N, H, W)
        Corrected frames ``(y_k − o)/g``, counts-like (the input's level and scale, not
        radiometric). A detector whose fitted gain is outside
        :data:`~thermocal.nuc._common.GAIN_RANGE` of the median (dead, stuck, hot) shows the
        fitted scene ``W_k(x)`` instead.

    Raises
    ------
    InvalidInputError
        Too few frames, NaN, wrong shape, a bad option, or torch not installed.
    """
    y = as_nuc_frames(frames, min_frames=2)
    n, hh, w = y.shape
    iterations = check_int(iterations, "iterations")
    seed = check_int(seed, "seed", minimum=0)
    channels = check_int(channels, "channels")
    scales = check_int(scales, "scales")
    lr = check_positive(learning_rate, "learning_rate")
    lr_motion = check_positive(motion_learning_rate, "motion_learning_rate")
    lam_x = 0.1 / n if scene_tv is None else _check_weight(scene_tv, "scene_tv")
    lam_o = _check_weight(offset_smoothness, "offset_smoothness")
    lam_g = _check_weight(gain_prior, "gain_prior")
    if homographies is None:
        from thermocal.registration import register_burst

        hs = register_burst(y).homographies
    else:
        from thermocal.registration.warp import as_homographies

        hs = as_homographies(homographies, "homographies", n=n)
    from thermocal.optional import require

    torch = require("torch", "deepir", "nn")
    if device not in ("auto", "cpu", "cuda"):
        raise InvalidInputError(f"deepir: device must be auto, cpu or cuda, not {device!r}")
    if device == "cuda" and not torch.cuda.is_available():
        raise InvalidInputError("deepir: device cuda asked for, but torch sees no CUDA GPU")
    dev = torch.device("cuda" if device != "cpu" and torch.cuda.is_available() else "cpu")

    # frames to about [0.1, 0.9], the range of the network's sigmoid
    lo, hi = (float(v) for v in np.percentile(y, [1.0, 99.0]))
    span = (hi - lo) / 0.8 if hi > lo else 1.0
    base = lo - 0.1 * span
    x0, y0, hc, wc = _canvas(hs, hh, w)
    # where each detector of each frame looks in the canvas (pixels), and the validity mask
    cols, rows = np.meshgrid(np.arange(w, dtype=float), np.arange(hh, dtype=float))
    pts = np.stack([cols, rows, np.ones_like(cols)], -1)  # (H, W, 3)
    q = np.einsum("nij,hwj->nhwi", hs, pts)
    q = q[..., :2] / q[..., 2:3] - np.array([x0, y0])
    valid = ((q[..., 0] >= 0) & (q[..., 0] <= wc - 1) & (q[..., 1] >= 0)
             & (q[..., 1] <= hc - 1))
    s = 0.5 * max(hh, w)
    rel = (pts[..., :2] - np.array([(w - 1) / 2, (hh - 1) / 2])) / s  # (H, W, 2), about ±1
    scales = max(1, min(scales, int(np.log2(min(hc, wc) / 2))))

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        f32 = torch.float32
        t_y = torch.as_tensor((y - base) / span, dtype=f32)[:, None].to(dev)
        t_q = torch.as_tensor(q, dtype=f32).to(dev)
        t_rel = torch.as_tensor(rel, dtype=f32).to(dev)
        t_valid = torch.as_tensor(valid, dtype=f32)[:, None].to(dev)
        norm = torch.tensor([2.0 / max(wc - 1, 1), 2.0 / max(hc - 1, 1)], dtype=f32).to(dev)
        z = (0.1 * torch.rand(1, 8, hc, wc)).to(dev)  # drawn on the CPU: the same on any device
        net = _skip_net(torch, 8, channels, 4, scales).to(dev)
        gain = torch.ones(1, 1, hh, w, device=dev, requires_grad=True)
        offset = torch.zeros(1, 1, hh, w, device=dev, requires_grad=True)
        motion = torch.zeros(n, 2, 3, device=dev, requires_grad=True)  # translation | linear
        opt = torch.optim.Adam([*net.parameters(), gain, offset], lr=lr, foreach=True)
        opt_motion = torch.optim.Adam([motion], lr=lr_motion)
        n_valid = t_valid.sum().clamp_min(1.0)
        best, best_state = float("inf"), None
        for _ in range(iterations):
            scene = net(z)  # (1, 1, Hc, Wc)
            pos = t_q
            if refine_motion:
                pos = pos + motion[:, None, None, :, 0] + torch.einsum(
                    "nij,hwj->nhwi", motion[:, :, 1:], t_rel)
            views = torch.nn.functional.grid_sample(
                scene.expand(n, -1, -1, -1), pos * norm - 1.0, mode="bilinear",
                padding_mode="border", align_corners=True)
            data = ((gain * views + offset - t_y).abs() * t_valid).sum() / n_valid
            tv_x = ((scene[..., 1:, :] - scene[..., :-1, :]).abs().mean()
                    + (scene[..., :, 1:] - scene[..., :, :-1]).abs().mean())
            tv_o = ((offset[..., 1:, :] - offset[..., :-1, :]).square().mean()
                    + (offset[..., :, 1:] - offset[..., :, :-1]).square().mean())
            loss = data + lam_x * tv_x + lam_o * tv_o + lam_g * (gain - 1.0).square().mean()
            value = float(loss.detach())
            if value < best:  # the parameters this loss was computed with
                best = value
                best_state = [t.detach().clone() for t in (gain, offset, views)]
            opt.zero_grad()
            opt_motion.zero_grad()
            loss.backward()
            opt.step()
            if refine_motion:
                opt_motion.step()
        g, o, v = (t.cpu().numpy()[:, 0].astype(np.float64) for t in best_state)

    # (y − o)/g in normalised units, back to the input's counts; a detector whose gain left the
    # physical range (dead, stuck or hot: the L1 fit drives its gain anywhere) shows the
    # network's scene instead, W_k(x)
    rel_g = g / np.median(g)
    ok = (rel_g > GAIN_RANGE[0]) & (rel_g < GAIN_RANGE[1])
    out = np.where(ok, ((y - base) / span - o) / np.where(ok, g, 1.0), v) * span + base
    return out.astype(np.float32)
