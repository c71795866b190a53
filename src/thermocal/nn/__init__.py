"""Multi-frame temperature estimation: the kernel prediction network (KPN) of Oz et al.

Modules (torch and kornia are imported only inside this package, and only by the modules that
need them; importing :mod:`thermocal.nn` itself, :mod:`thermocal.nn.data` or
:mod:`thermocal.nn.commands` does not import torch):

``data``      synthetic bursts from the camera simulator (§IV-C, IV-D), numpy only
``model``     the UNet + kernel-prediction head, the offset block (eq. 10, 11), the E2E ablation
``loss``      eq. 12: masked L1 + Sobel-gradient L1 + SSIM loss
``train``     training loop, checkpoints, the weights file
``infer``     tiled inference on a burst of any size (validation, registration and the naive
              mean of eq. 9 are in :mod:`thermocal.burst`, without torch)
``commands``  ``thermocal estimate`` and ``thermocal train``
"""
