"""Registration of raw thermal frames: homographies, bursts to a pivot, warping with valid masks.

Public API::

    register_pair(moving, fixed, *, method="auto", fixed_pattern=None) -> (H (3, 3), inliers)
    register_burst(frames, *, pivot=None, method="auto", fixed_pattern=None) -> BurstRegistration
    register_sequence(frames, *, fixed_pattern=None, block=512, workers=None, progress=None,
                      pairs=None) -> SequenceRegistration
    estimate_fixed_pattern(frames, *, max_frames=256) -> FixedPattern
    warp_to_pivot(frames, homographies_to_pivot, *, interpolation="linear") -> (warped, valid)
    render_views(map_c, homographies, frame_size) -> views
"""

from thermocal.registration.burst import (
    BURST_METHODS,
    BurstRegistration,
    register_burst,
    register_pair,
)
from thermocal.registration.features import normalise_frame
from thermocal.registration.fixed_pattern import FixedPattern, estimate_fixed_pattern
from thermocal.registration.sequence import SequenceRegistration, register_sequence
from thermocal.registration.warp import as_homographies, render_views, warp_to_pivot

__all__ = [
    "BURST_METHODS",
    "BurstRegistration",
    "FixedPattern",
    "SequenceRegistration",
    "as_homographies",
    "estimate_fixed_pattern",
    "normalise_frame",
    "register_burst",
    "register_pair",
    "register_sequence",
    "render_views",
    "warp_to_pivot",
]
