"""The training loss of Oz et al. eq. 12 (kornia for the Sobel operator and SSIM).

``L = ‖M(X̂) − M(X)‖₁ + λ1 ‖M(∇X̂) − M(∇X)‖₁ + λ2 · L_SSIM(M(X̂), M(X))`` with ``∇`` the magnitude
of the Sobel gradients, ``M`` the mask of valid pixels, ``λ1 = 0.1``, ``λ2 = 0.01``. The L1 terms
are means over the valid pixels.
"""

from __future__ import annotations

import kornia
import torch

__all__ = ["LAMBDA_GRAD", "LAMBDA_SSIM", "kpn_loss", "masked_l1"]

LAMBDA_GRAD = 0.1
LAMBDA_SSIM = 0.01


def masked_l1(a: torch.Tensor, b: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Mean ``|a − b|`` over the pixels where ``mask`` is True; tensors ``(B, 1, H, W)``."""
    m = mask.to(a.dtype)
    return ((a - b).abs() * m).sum() / m.sum().clamp_min(1.0)


def kpn_loss(
    estimate: torch.Tensor,
    truth: torch.Tensor,
    mask: torch.Tensor,
    *,
    lambda_grad: float = LAMBDA_GRAD,
    lambda_ssim: float = LAMBDA_SSIM,
) -> torch.Tensor:
    """Eq. 12 on normalised temperatures ``(B, 1, H, W)``; ``mask`` bool ``(B, 1, H, W)``."""
    fidelity = masked_l1(estimate, truth, mask)
    grad = masked_l1(kornia.filters.sobel(estimate), kornia.filters.sobel(truth), mask)
    m = mask.to(estimate.dtype)
    ssim = kornia.losses.ssim_loss(estimate * m, truth * m, window_size=7, max_val=1.0)
    return fidelity + lambda_grad * grad + lambda_ssim * ssim
