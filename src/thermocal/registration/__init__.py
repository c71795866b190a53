"""Registration of raw thermal frames: homographies, bursts to a pivot, warping with valid masks.

Public API
----------
register_pair(moving, fixed, *, method="auto") -> (H (3, 3), inliers)
register_burst(frames, *, pivot=None, method="auto") -> BurstRegistration
warp_to_pivot(frames, homographies_to_pivot, *, interpolation="linear") -> (warped, valid)
render_views(map_c, homographies, frame_size) -> views
"""

from thermocal.registration.burst import BURST_METHODS, BurstRegistration, register_burst
from thermocal.registration.features import normalise_frame, register_pair
from thermocal.registration.warp import as_homographies, render_views, warp_to_pivot

__all__ = [
    "BURST_METHODS",
    "BurstRegistration",
    "as_homographies",
    "normalise_frame",
    "register_burst",
    "register_pair",
    "render_views",
    "warp_to_pivot",
]
