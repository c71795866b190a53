"""The kernel prediction network with offset block of Oz et al. (appendix, Fig. 6, Tables I-II).

Shapes follow kornia: tensors are ``(B, C, H, W)``; a burst is ``(B, N, H, W)`` of normalised
gray levels registered onto the pivot (eq. 21), the FPA temperature ``(B,)`` normalised (eq. 20).

* :class:`UNet`: an input 3×3 conv ``N → μ`` (no activation); ``L`` encoder blocks of three 3×3
  convs (GeLU + batch norm on the first two, neither on the last, which multiplies the channels by
  ``ξ``) each followed by ``ξ × ξ`` average pooling; a bottleneck block; ``L`` decoder blocks fed
  with the pixel-shuffled (×ξ) lower level concatenated with the encoder output of their level.
* :class:`KernelHead`: three 1×1 convs (GeLU on the first two) giving ``N·K²`` channels.
* :func:`apply_kernels`: eq. 11, the per-pixel ``K × K`` kernel of every frame applied to the
  ``K × K`` patch of that frame around the pixel, summed over frames.
  :meth:`KernelHead.kernel_sum` computes the same sum without forming the ``N·K²`` kernels:
  the head's last 1×1 conv and eq. 11 are both linear, so they fold into one ``K × K`` conv of
  the frames (``μ + 1`` output channels, :func:`fold_kernel_conv`) and a ``μ``-channel product
  per pixel (:func:`apply_folded_kernels`). What :class:`KPN` runs, in training and inference:
  the same multiply-adds, but none of the ``N·K²``-channel tensors (kernels, patches) that made
  the kernel step half of eager's time (2× faster eager on one 336×256 burst, 2 threads) and,
  in the exported graph, gathers and layout reorders around the convolutions; equal to 1e-5 °C
  (``benchmarks/backends.py``). :func:`with_formed_kernels` gives the network as it was.
* :class:`OffsetBlock`: eq. 10, a polynomial of degree ν in each frame's mean gray level and in
  the FPA temperature, averaged over frames; with ``radial > 0`` (an addition to the paper) also
  in the pixel's ``R²`` on the sensor, a radial offset map (the UNet then sees ``R²`` too).
* :class:`RadianceToTemperature`: with ``radiance=True`` (an addition to the paper) the kernels
  and the offset give band radiance, turned into temperature by the inverse of Planck's band
  integral.
* :class:`KPN`: the whole model; ``variant="kpn"`` (with the offset block), ``"kpn-no-offset"``
  and ``"e2e"`` (the same UNet with a head that predicts the temperature directly).
"""

from __future__ import annotations

import numbers
from dataclasses import asdict, dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError
from thermocal.nn.variants import VARIANTS
from thermocal.radiometry import TAU2_BAND_M, band_radiance

__all__ = [
    "KPN",
    "VARIANTS",
    "KernelHead",
    "ModelConfig",
    "OffsetBlock",
    "RadianceToTemperature",
    "UNet",
    "apply_folded_kernels",
    "apply_kernels",
    "count_macs",
    "count_parameters",
    "fold_kernel_conv",
    "frame_means",
    "with_formed_kernels",
]


#: Bounds of the integer sizes of :class:`ModelConfig` (inclusive). They hold every network
#: thermocal ships or its presets train (the shipped ``N=7, μ=16, ξ=2, L=3, K=5, ν=4, ρ=2``; the
#: paper's ``μ=64, L=4``) with room to experiment, and keep a configuration read from a damaged
#: file from asking for absurd sizes: ``n_frames`` 1…31 (a burst; the paper uses 7), ``mu`` 1…256
#: channels, ``xi`` 1…4, ``levels`` 0…6, ``kernel`` 1…15 (odd), ``degree`` 0…8 (the offset
#: polynomial has ``(ν+1)²`` terms per frame), ``radial`` 0…8.
SIZE_LIMITS: dict[str, tuple[int, int]] = {
    "n_frames": (1, 31), "mu": (1, 256), "xi": (1, 4), "levels": (0, 6), "kernel": (1, 15),
    "degree": (0, 8), "radial": (0, 8),
}
#: Largest ``ξ^L``: frames (and each inference tile) are zero-padded to a multiple of it, and
#: training crops must be one (the shipped network: 8, the paper's: 16).
MAX_MULTIPLE = 64
#: The spectral band ``(λ1, λ2)`` must lie within these, m (a thermal camera's MWIR or LWIR band;
#: the same bounds as a calibration file's).
BAND_LIMITS_M = (1e-6, 30e-6)


@dataclass(frozen=True)
class ModelConfig:
    """Sizes of the network (the paper: ``mu=64, xi=2, levels=4``).

    Every field is checked when it is made (:class:`~thermocal.errors.InvalidInputError`): the
    sizes are integers within :data:`SIZE_LIMITS` with ``ξ^L <= MAX_MULTIPLE``, the switches
    booleans, ``band_m`` within :data:`BAND_LIMITS_M`.

    Attributes
    ----------
    n_frames : int
        Frames per burst ``N``.
    mu : int
        Channels after the input conv, ``μ``.
    xi : int
        Channel factor and pooling / pixel-shuffle factor per level, ``ξ``.
    levels : int
        Number of encoder (and decoder) levels, ``L``.
    kernel : int
        Side ``K`` of the predicted per-pixel kernels (odd).
    degree : int
        Degree ``ν`` of the offset polynomial (eq. 10).
    variant : {"kpn", "kpn-no-offset", "e2e"}
        KPN with offset block, KPN alone, or end-to-end UNet.
    fpa_input : bool
        Also feed the normalised FPA temperature to the UNet as a constant input plane (an
        addition to the paper, which gives it to the offset block only: it lets the kernels,
        i.e. the gain of eq. 11, follow the FPA temperature).
    centre : bool
        Only with the offset block (``variant="kpn"``): the kernels of eq. 11 are applied to the
        frames minus the burst's mean gray level ``μ`` (the mean of the frame means), so that
        the offset block, which is given the frame means, carries the whole level and the kernels
        only the contrast. An addition to the paper: with raw levels (≈ 0.4 after eq. 21) every
        relative error of a predicted kernel sum is multiplied by the level, not by the scene's
        contrast. With ``fpa_input`` the UNet is also given ``μ`` as a constant plane.
    radiance : bool
        The network's linear output (eq. 11's kernels plus eq. 10's offset, or the E2E head) is
        the scene's band radiance, normalised like eq. 20 over the same temperature range, and
        the exact inverse of the band integral turns it into the normalised temperature. An
        addition to the paper, from the camera physics: raw counts are affine in band radiance
        (a gain and an offset per pixel), so a linear combination of gray levels is a radiance
        and the FPA's offset drift adds to it; in temperature the kernels would have to follow
        Planck's curve pixel by pixel (dL/dT changes 2.3-fold between −20 and 60 °C).
    band_m : (float, float)
        The camera's spectral band ``(λ1, λ2)``, m, for ``radiance`` (default: the Tau2's).
    radial : int
        Degree ``ρ`` in ``R²`` of position terms (0: none, the paper). ``R²`` is the pivot
        pixel's squared distance from the sensor's centre (Oz et al. eq. 16, axes −0.5 … 0.5).
        The UNet is also given the ``R²`` plane, and the offset block's polynomial gets the
        factors ``R^(2k)``, ``k = 1 … ρ``, so that it gives a radial offset map rather than one
        number. An addition to the paper: a convolutional network trained on crops cannot tell
        where on the sensor a pixel lies, so without it the radial offset and vignetting of
        eq. 16-17 (degrees between the centre and the corners) are left to the burst's
        parallax, and a camera that hovers has none.
    radial_frames : bool
        With ``radial``: the position terms take, for each frame, where on the sensor it saw
        each pivot pixel (``R²`` of its pixels warped onto the pivot, ``N`` planes;
        :func:`~thermocal.nn.inputs.frame_r2`) instead of the pivot's position alone, and the
        offset block's radial polynomial of frame ``n`` is evaluated at frame ``n``'s ``R²``.
        An addition: in a walk the other frames see a scene point far from where the pivot
        does, under another radial offset and vignetting.
    calibrated : bool
        The frames reach the network through the exact inverse of the *nominal* camera model it
        was trained from (the average of the preset's training units, or the model fitted on the
        chamber file; :func:`~thermocal.nn.inputs.calibrate_frames`, on the sensor before
        warping), in the units of its linear output (normalised band radiance with
        ``radiance``, else eq. 20's normalised temperature), instead of as raw counts (eq. 21).
        An addition to the paper: the untrained network then starts from eq. 9 through that
        model, and learns only what the model gets wrong for the unit at hand (its offset and
        gain, its FPN). :attr:`KPN.nominal` holds the model at inference.
    """

    n_frames: int = 7
    mu: int = 64
    xi: int = 2
    levels: int = 4
    kernel: int = 5
    degree: int = 4
    variant: str = "kpn"
    fpa_input: bool = False
    centre: bool = False
    radiance: bool = False
    radial: int = 0
    band_m: tuple[float, float] = TAU2_BAND_M
    radial_frames: bool = False
    calibrated: bool = False

    def __post_init__(self) -> None:
        for name, (lo, hi) in SIZE_LIMITS.items():
            value = getattr(self, name)
            if not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_)):
                raise InvalidInputError(f"{name} must be an integer, got {value!r:.40}")
            if not lo <= value <= hi:
                raise InvalidInputError(f"{name} must be in {lo}…{hi}, got {value}")
            object.__setattr__(self, name, int(value))
        for name in ("fpa_input", "centre", "radiance", "radial_frames", "calibrated"):
            value = getattr(self, name)
            if not isinstance(value, (bool, np.bool_)):
                raise InvalidInputError(f"{name} must be true or false, got {value!r:.40}")
            object.__setattr__(self, name, bool(value))
        if not isinstance(self.variant, str) or self.variant not in VARIANTS:
            raise InvalidInputError(f"variant {self.variant!r:.40}: choose from "
                                    f"{', '.join(VARIANTS)}")
        if self.centre and self.variant != "kpn":
            raise InvalidInputError("centre needs the offset block (variant 'kpn')")
        if self.kernel % 2 == 0:
            raise InvalidInputError(f"kernel size must be odd, got {self.kernel}")
        if self.multiple > MAX_MULTIPLE:
            raise InvalidInputError(
                f"ξ^L = {self.xi}^{self.levels} = {self.multiple} is above {MAX_MULTIPLE} "
                "(frames are padded to a multiple of it)"
            )
        if self.radial_frames and not self.radial:
            raise InvalidInputError("radial_frames needs position terms (radial > 0)")
        try:  # a list when read back from JSON
            band = tuple(float(v) for v in self.band_m)
        except (TypeError, ValueError):
            raise InvalidInputError(f"band_m must be (λ1, λ2) in m; got {self.band_m!r:.60}"
                                    ) from None
        lo, hi = BAND_LIMITS_M
        if len(band) != 2 or not lo <= band[0] < band[1] <= hi:
            raise InvalidInputError(
                f"band_m must be (λ1, λ2) in m, increasing, within {lo:g}…{hi:g}; got {band}"
            )
        object.__setattr__(self, "band_m", band)

    @property
    def multiple(self) -> int:
        """Frame sides must be a multiple of this (``ξ^L``)."""
        return self.xi**self.levels

    @property
    def position_planes(self) -> int:
        """``R²`` planes the model takes: 0 (no position terms), 1 (the pivot's), ``N``."""
        if not self.radial:
            return 0
        return self.n_frames if self.radial_frames else 1

    def to_dict(self) -> dict:
        """JSON-able form."""
        return asdict(self)


def _block(c_in: int, c_mid: int, c_out: int) -> nn.Sequential:
    """Table I: conv-BN-GeLU, conv-BN-GeLU, conv (3×3, 'same' padding)."""
    return nn.Sequential(
        nn.Conv2d(c_in, c_mid, 3, padding=1),
        nn.BatchNorm2d(c_mid),
        nn.GELU(),
        nn.Conv2d(c_mid, c_mid, 3, padding=1),
        nn.BatchNorm2d(c_mid),
        nn.GELU(),
        nn.Conv2d(c_mid, c_out, 3, padding=1),
    )


class UNet(nn.Module):
    """Encoder-decoder of the appendix; returns ``μ`` feature channels at full resolution.

    Level ``i`` (0 = full resolution) works with ``μ·ξ^i`` channels; its encoder block outputs
    ``μ·ξ^(i+1)`` (Table I) before pooling. The decoder block of level ``i`` takes the
    pixel-shuffled output of the level below concatenated with that encoder output and gives
    ``μ·ξ^(i+1)`` channels (``μ`` at level 0), so that the next pixel shuffle has ``μ·ξ^(i−1)``.
    """

    def __init__(self, c_in: int, mu: int, xi: int, levels: int) -> None:
        super().__init__()
        self.xi, self.levels = xi, levels
        self.inp = nn.Conv2d(c_in, mu, 3, padding=1)
        self.enc = nn.ModuleList(
            _block(mu * xi**i, mu * xi**i, mu * xi ** (i + 1)) for i in range(levels)
        )
        c_bottom = mu * xi**levels
        self.bottom = _block(c_bottom, c_bottom, c_bottom * xi) if levels else _block(mu, mu, mu)
        dec = []
        for i in range(levels):
            c_up = mu * xi**i  # pixel shuffle (×ξ) of the μ·ξ^(i+2) channels from below
            c_skip = mu * xi ** (i + 1)
            c_out = mu * xi ** (i + 1) if i else mu
            dec.append(_block(c_up + c_skip, mu * xi**i, c_out))
        self.dec = nn.ModuleList(dec)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, C_in, H, W) → (B, μ, H, W)``; ``H, W`` multiples of ``ξ^L``."""
        x = self.inp(x)
        skips = []
        for block in self.enc:
            x = block(x)
            skips.append(x)
            x = F.avg_pool2d(x, self.xi)
        x = self.bottom(x)
        for i in reversed(range(self.levels)):
            x = F.pixel_shuffle(x, self.xi)
            x = self.dec[i](torch.cat([x, skips[i]], dim=1))
        return x


class KernelHead(nn.Module):
    """Table II: 1×1 conv-GeLU, 1×1 conv-GeLU, 1×1 conv to ``c_out`` channels."""

    def __init__(self, mu: int, c_out: int) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(mu, mu, 1),
            nn.GELU(),
            nn.Conv2d(mu, mu, 1),
            nn.GELU(),
            nn.Conv2d(mu, c_out, 1),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """``(B, μ, H, W) → (B, c_out, H, W)``."""
        return self.net(x)

    def kernel_sum(self, frames: torch.Tensor, x: torch.Tensor, k: int) -> torch.Tensor:
        """Eq. 11 with the kernels this head makes from features ``x (B, μ, H, W)``, applied to
        ``frames (B, N, H, W)`` (``apply_kernels(frames, self(x), k)``), folded
        (:func:`apply_folded_kernels`); ``(B, 1, H, W)``."""
        last = self.net[-1]
        return apply_folded_kernels(frames, self.net[:-1](x),
                                    fold_kernel_conv(last.weight, last.bias, frames.shape[1], k),
                                    k)


def apply_kernels(frames: torch.Tensor, kernels: torch.Tensor, k: int) -> torch.Tensor:
    """Eq. 11 (first term): ``Σ_n ⟨K_n^p, S^p(I_n)⟩`` for every pixel ``p``.

    Parameters
    ----------
    frames : (B, N, H, W) tensor
        Registered, normalised frames.
    kernels : (B, N·K², H, W) tensor
        Per-pixel kernels, frame-major (channel ``n·K² + j`` is tap ``j`` of frame ``n``).
    k : int
        Kernel side ``K``; patches outside the frame are zero-padded.

    Returns
    -------
    (B, 1, H, W) tensor
    """
    b, n, h, w = frames.shape
    if kernels.shape != (b, n * k * k, h, w):
        raise InvalidInputError(
            f"kernels {tuple(kernels.shape)} do not match frames {(b, n, h, w)}"
        )
    patches = F.unfold(frames, k, padding=k // 2).view(b, n * k * k, h, w)
    return (patches * kernels).sum(dim=1, keepdim=True)


def fold_kernel_conv(weight: torch.Tensor, bias: torch.Tensor, n_frames: int, k: int
                     ) -> torch.Tensor:
    """The kernel head's last 1×1 conv (``weight (N·K², μ, 1, 1)``, ``bias (N·K²,)``, frame-major
    taps as :func:`apply_kernels` reads them) as the weight ``(μ + 1, N, K, K)`` of one ``K × K``
    conv of the frames: output channel ``m < μ`` is ``Σ_n Σ_j W[n·K² + j, m] · S_j(I_n)``, the last
    the same with the bias. A differentiable function of the parameters (a new tensor)."""
    if k < 1 or k % 2 == 0 or weight.shape[0] != n_frames * k * k or weight.shape[2:] != (1, 1) \
            or bias.shape != (n_frames * k * k,):
        raise InvalidInputError(
            f"a 1×1 conv to {n_frames}·{k}² kernel taps (odd K) is needed, got weight "
            f"{tuple(weight.shape)}, bias {tuple(bias.shape)}")
    mu = weight.shape[1]
    taps = weight.reshape(n_frames, k, k, mu).permute(3, 0, 1, 2)
    return torch.cat([taps, bias.reshape(1, n_frames, k, k)], dim=0)


def apply_folded_kernels(frames: torch.Tensor, hidden: torch.Tensor, folded: torch.Tensor,
                         k: int) -> torch.Tensor:
    """Eq. 11 through the folded head: ``Σ_m h_m · (F * I)_m + (F * I)_μ`` with ``h = hidden
    (B, μ, H, W)`` (the head before its last conv), ``F = folded`` (:func:`fold_kernel_conv`) and
    ``frames I (B, N, H, W)`` zero-padded as in :func:`apply_kernels`; ``(B, 1, H, W)``."""
    b, n, h, w = frames.shape
    mu = hidden.shape[1]
    if folded.shape != (mu + 1, n, k, k) or hidden.shape != (b, mu, h, w):
        raise InvalidInputError(
            f"folded kernels {tuple(folded.shape)} and features {tuple(hidden.shape)} do not "
            f"match frames {(b, n, h, w)} and K = {k}")
    q = F.conv2d(frames, folded, padding=k // 2)
    return (hidden * q[:, :-1]).sum(dim=1, keepdim=True) + q[:, -1:]


def with_formed_kernels(model: KPN) -> KPN:
    """A copy of ``model`` that forms its head's ``N·K²`` kernels and applies them
    (:func:`apply_kernels`) instead of the folded sum: the network as it ran before the folding,
    the same numbers to float rounding (the baseline of ``benchmarks/backends.py``)."""
    import copy

    formed = copy.deepcopy(model)
    formed.head.__class__ = _FormedKernelHead
    return formed


class OffsetBlock(nn.Module):
    """Eq. 10: ``d = (1/N) Σ_n Σ_{i,j=0..ν} δ_{n,i,j} · mean(I_n)^i · t^j``.

    The appendix realises the coefficients as an ``N × (ν+1)`` weight matrix; with the powers of
    the FPA (ambient) temperature ``t`` of eq. 10 each frame has ``(ν+1)²`` coefficients here,
    one matrix ``(N, (ν+1)²)``: a single matrix product gives all the frames' offsets.
    Inputs are normalised (eq. 20-21), so the powers stay in ``[0, 1]``. Starts at zero.

    With ``radial = ρ > 0`` (:class:`ModelConfig`) a second matrix ``(N, (ν+1)², ρ)`` gives the
    coefficients of ``R^(2k)``, ``k = 1 … ρ``: the offset becomes a radial map. ``R²`` is the
    pivot's (one plane) or each frame's own (``N`` planes, frame ``n``'s terms at its ``R²``).
    """

    def __init__(self, n_frames: int, degree: int, radial: int = 0) -> None:
        super().__init__()
        self.degree, self.radial = degree, radial
        self.delta = nn.Parameter(torch.zeros(n_frames, (degree + 1) ** 2))
        self.delta_radial = (
            nn.Parameter(torch.zeros(n_frames, (degree + 1) ** 2, radial)) if radial else None
        )

    def forward(
        self, means: torch.Tensor, fpa: torch.Tensor, r2: torch.Tensor | None = None
    ) -> torch.Tensor:
        """``means (B, N)``, ``fpa (B,)`` [, ``r2 (B, 1 or N, H, W)``] → offset
        ``(B, 1, 1, 1)`` (``(B, 1, H, W)`` with radial terms)."""
        p = torch.arange(self.degree + 1, dtype=means.dtype, device=means.device)
        m_pow = means[..., None] ** p  # (B, N, ν+1)
        t_pow = fpa[:, None] ** p  # (B, ν+1)
        feats = (m_pow[..., :, None] * t_pow[:, None, None, :]).flatten(2)  # (B, N, (ν+1)²)
        d = (feats * self.delta).sum(dim=2).mean(dim=1).view(-1, 1, 1, 1)
        if self.delta_radial is None:
            return d
        if r2 is None:
            raise InvalidInputError("the radial offset block needs the pixels' R² (B, 1|N, H, W)")
        coef = torch.einsum("bnf,nfk->bnk", feats, self.delta_radial)  # (B, N, ρ)
        if r2.shape[1] == 1:  # the pivot's R² for every frame: one map, the mean coefficients
            coef = coef.mean(dim=1, keepdim=True)
        for k in range(self.radial):  # frame n's terms at its R², averaged over the frames
            d = d + (coef[:, :, k, None, None] * r2 ** (k + 1)).mean(dim=1, keepdim=True)
        return d


class RadianceToTemperature(nn.Module):
    """Normalised band radiance → normalised temperature (eq. 20), both over ``temp_range_c``.

    ``x̄ = (L(T) − L(t_min)) / (L(t_max) − L(t_min))`` with ``L`` the band integral of Planck's
    law (:func:`thermocal.radiometry.band_radiance`, Tau2 band by default) is inverted exactly
    by a table on a 0.02 K grid, ``margin_c`` beyond the range on both sides, with linear
    interpolation (error < 1e-4 K; beyond the table, its end segments extended, so that the
    gradient never vanishes). The band must be that of the camera that made the training data
    (:class:`ModelConfig` ``band_m``). The table is built from the range, never stored in a
    weights file. Parameter-free; differentiable in ``x̄``.
    """

    def __init__(
        self,
        temp_range_c: tuple[float, float] = (-40.0, 100.0),
        band_m: tuple[float, float] = TAU2_BAND_M,
        *,
        margin_c: float = 60.0,
        step_c: float = 0.02,
    ) -> None:
        super().__init__()
        lo, hi = (float(v) for v in temp_range_c)
        if not hi > lo:
            raise InvalidInputError(f"temperature range must increase, got {temp_range_c}")
        t_c = np.arange(max(lo - margin_c, -200.0), hi + margin_c + step_c, step_c)
        ends = band_radiance(np.array([lo, hi]) + ZERO_CELSIUS_K, band_m)
        x = (band_radiance(t_c + ZERO_CELSIUS_K, band_m) - ends[0]) / (ends[1] - ends[0])
        self.temp_range_c = (lo, hi)
        self.register_buffer("x_grid", torch.tensor(x, dtype=torch.float32), persistent=False)
        self.register_buffer(
            "t_grid", torch.tensor((t_c - lo) / (hi - lo), dtype=torch.float32), persistent=False
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Normalised radiance, any shape → normalised temperature, same shape."""
        return _interp(x, self.x_grid, self.t_grid)

    def radiance(self, t: torch.Tensor) -> torch.Tensor:
        """The other direction: normalised temperature → normalised radiance."""
        return _interp(t, self.t_grid, self.x_grid)


def _interp(x: torch.Tensor, xg: torch.Tensor, yg: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear ``y(x)`` through ``(xg, yg)`` (``xg`` increasing), extended by the end
    segments; differentiable in ``x``. torch has no 1-D interpolation: searchsorted + one
    segment."""
    xg, yg = xg.to(x.dtype), yg.to(x.dtype)
    i = torch.searchsorted(xg, x.detach().contiguous()).clamp(1, len(xg) - 1)
    x0, x1, y0, y1 = xg[i - 1], xg[i], yg[i - 1], yg[i]
    return y0 + (x - x0) * ((y1 - y0) / (x1 - x0))


class _FormedKernelHead(KernelHead):
    """:class:`KernelHead` forming its kernels (:func:`with_formed_kernels`)."""

    def kernel_sum(self, frames: torch.Tensor, x: torch.Tensor, k: int) -> torch.Tensor:
        return apply_kernels(frames, self(x), k)


class KPN(nn.Module):
    """The temperature estimation network: UNet → kernels (eq. 11) + offset block (eq. 10).

    ``forward(frames, fpa, valid, r2=r2)`` takes registered normalised frames
    ``(B, N, H, W)`` (0 where a frame does not see the pixel), the normalised FPA temperature
    ``(B,)``, optionally the validity masks ``(B, N, H, W)`` (for the frame means of the offset
    block; default: every pixel) and, for a model with ``radial > 0``, the pivot pixels'
    sensor position ``R² (B, 1, H, W)`` (with ``radial_frames``, each frame's: ``(B, N, H, W)``),
    and returns the normalised temperature of the pivot
    ``(B, 1, H, W)``. ``H, W`` must be multiples of ``ξ^L``. ``temp_range_c`` is eq. 20's
    temperature range (the normalisation's); only ``radiance=True`` uses it. ``train_crop`` is
    the side of the training crops, px (:func:`~thermocal.nn.store.load_model` sets it from the
    weights file): :func:`~thermocal.nn.infer.run_network` runs an E2E model in tiles of it.
    ``nominal`` is, for a ``calibrated`` model, the whole-sensor camera model that its input
    goes through (a :class:`~thermocal.camera.model.CameraModel`, not a parameter; set by
    :func:`~thermocal.nn.store.load_model`).
    """

    def __init__(
        self,
        config: ModelConfig,
        *,
        init: bool = True,
        temp_range_c: tuple[float, float] = (-40.0, 100.0),
        train_crop: int | None = None,
    ) -> None:
        super().__init__()
        self.config = config
        self.train_crop = train_crop
        self.nominal = None
        c = config
        extra = int(c.fpa_input) * (2 if c.centre else 1) + c.position_planes
        self.unet = UNet(c.n_frames + extra, c.mu, c.xi, c.levels)
        c_out = 1 if c.variant == "e2e" else c.n_frames * c.kernel**2
        self.head = KernelHead(c.mu, c_out)
        self.offset = OffsetBlock(c.n_frames, c.degree, c.radial) if c.variant == "kpn" else None
        self.to_temperature = (
            RadianceToTemperature(temp_range_c, c.band_m) if c.radiance else None
        )
        if init:  # skipped when weights are loaded next (orthogonal init of big layers is slow)
            self.reset_parameters()

    def reset_parameters(self, gain: float = 0.1) -> None:
        """Orthogonal initialisation of the weights scaled by ``gain`` (§IV-D), zero biases.

        One addition: the bias of the last kernel-head conv puts ``1/N`` on the centre tap of
        every frame's kernel, so that the untrained KPN starts from the plain average of the
        registered frames (eq. 9 with unit gain; with ``radiance``, that average read as a
        radiance) instead of from zero; the E2E head starts from the mean of the frames in the
        same way through its offset. This only shortens training.
        """
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.orthogonal_(m.weight, gain=gain)
                nn.init.zeros_(m.bias)
        c = self.config
        if c.variant != "e2e":
            last = self.head.net[-1]
            with torch.no_grad():
                bias = last.bias.view(c.n_frames, c.kernel**2)
                bias[:, (c.kernel**2) // 2] = 1.0 / c.n_frames
        if self.offset is not None:
            nn.init.zeros_(self.offset.delta)
            if self.offset.delta_radial is not None:
                nn.init.zeros_(self.offset.delta_radial)
            if c.centre:  # start from d = μ (the level the centring took away): δ_{n,1,0} = 1
                with torch.no_grad():
                    self.offset.delta[:, c.degree + 1] = 1.0

    def forward(
        self,
        frames: torch.Tensor,
        fpa: torch.Tensor,
        valid: torch.Tensor | None = None,
        *,
        means: torch.Tensor | None = None,
        r2: torch.Tensor | None = None,
        linear: bool = False,
    ) -> torch.Tensor:
        """See the class docstring; ``means (B, N)`` overrides the frame means (tiling);
        ``linear``: the linear output, before a ``radiance`` model turns it into temperature
        (what an exported graph holds: :mod:`thermocal.nn.backends`)."""
        c = self.config
        if frames.ndim != 4 or frames.shape[1] != c.n_frames:
            raise InvalidInputError(
                f"expected frames (B, {c.n_frames}, H, W), got {tuple(frames.shape)}"
            )
        b, _, h, w = frames.shape
        if h % c.multiple or w % c.multiple:
            raise InvalidInputError(f"frame sides must be multiples of {c.multiple}, got {h}x{w}")
        want = (b, c.position_planes, h, w)
        if c.radial and (r2 is None or tuple(r2.shape) != want):
            got = None if r2 is None else tuple(r2.shape)
            raise InvalidInputError(
                f"this model needs the pixels' sensor position R² {want}, got {got}"
            )
        if means is None:
            means = frame_means(frames, valid)
        planes = []
        if c.centre:
            level = means.mean(dim=1).view(b, 1, 1, 1)
            frames = frames - level
            if valid is not None:
                frames = frames * valid.to(frames.dtype)
            if c.fpa_input:
                planes.append(level.expand(b, 1, h, w))
        if c.fpa_input:
            planes.insert(0, fpa.view(b, 1, 1, 1).expand(b, 1, h, w).to(frames.dtype))
        if c.radial:
            planes.append(r2.to(frames.dtype))
        x = torch.cat([frames, *planes], dim=1) if planes else frames
        feats = self.unet(x)
        if c.variant == "e2e":
            out = self.head(feats) + means.mean(dim=1).view(b, 1, 1, 1)
        else:
            out = self.head.kernel_sum(frames, feats, c.kernel)
            if self.offset is not None:
                out = out + self.offset(means, fpa, r2)
        return out if self.to_temperature is None or linear else self.to_temperature(out)


def frame_means(frames: torch.Tensor, valid: torch.Tensor | None) -> torch.Tensor:
    """Mean of each frame over its valid pixels, ``(B, N)``."""
    if valid is None:
        return frames.mean(dim=(2, 3))
    v = valid.to(frames.dtype)
    return (frames * v).sum(dim=(2, 3)) / v.sum(dim=(2, 3)).clamp_min(1.0)


def count_parameters(model: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad)


def count_macs(model: KPN, height: int, width: int) -> int:
    """Multiply-accumulates of one forward pass on a ``height × width`` burst: the convs and
    eq. 11 as :class:`KPN` computes it (:meth:`KernelHead.kernel_sum`: the folded ``K × K`` conv and
    the ``μ``-channel product, in place of the head's last conv and the kernels' products)."""
    macs = 0

    def hook(mod: nn.Module, inp: tuple, out: torch.Tensor) -> None:
        nonlocal macs
        k = mod.kernel_size[0] * mod.kernel_size[1]
        macs += out.numel() * mod.in_channels * k // mod.groups

    handles = [m.register_forward_hook(hook) for m in model.modules() if isinstance(m, nn.Conv2d)]
    c = model.config
    was_training = model.training
    model.eval()
    try:
        with torch.no_grad():
            model(torch.zeros(1, c.n_frames, height, width), torch.zeros(1),
                  r2=torch.zeros(1, c.position_planes, height, width) if c.radial else None)
    finally:
        for h in handles:
            h.remove()
        model.train(was_training)
    if c.variant != "e2e":
        macs += ((c.mu + 1) * c.n_frames * c.kernel**2 + c.mu) * height * width
    return int(macs)
