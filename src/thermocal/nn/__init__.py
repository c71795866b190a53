"""Multi-frame temperature estimation: the kernel prediction network (KPN) of Oz et al.

Modules (torch and kornia are imported only by the modules that need them; importing
:mod:`thermocal.nn` itself, ``variants``, ``inputs``, ``data`` or ``commands`` does not import
torch):

============ ==================================================================================
``variants`` the network variants by name (the estimator registry reads it)
``inputs``   what the network is given: normalisation (eq. 20-21), input planes, sensor
             position, the nominal camera its frames go through (numpy only)
``data``     synthetic bursts from the camera simulator (§IV-C, IV-D), numpy only
``model``    the UNet + kernel-prediction head, the offset block (eq. 10, 11), the E2E ablation
``loss``     eq. 12: masked L1 + Sobel-gradient L1 + SSIM loss
``store``    the weights file: self-contained (the nominal camera stored, checksummed)
``train``    the :class:`~thermocal.nn.train.Trainer`, its checkpoints and ``train()``
``infer``    the network as an estimator of :mod:`thermocal.estimation`, tiled inference
``commands`` ``thermocal train``
============ ==================================================================================
"""
