"""How much a simulation holds at once: frames rendered per chunk, and the working memory a run
needs (checked before the camera model is made, :func:`thermocal._validate.check_data_size`).

The figures were measured on the ``tau2`` preset (peak resident memory of ``make_camera`` and
``render`` at 512² to 2048² pixels).
"""

from __future__ import annotations

#: Pixels rendered at once (frames × H × W of a chunk): 2**26, about 1.8 GiB of working memory.
#: It keeps the chunks (and so the files, byte for byte) of every flight of frames up to
#: 1024x1024 and every chamber session up to 640x512 as they were; larger frames are rendered
#: fewer at a time. Every frame draws its own noise: the chunk size never changes a frame.
CHUNK_PIXELS = 2**26

#: Bytes per pixel of a camera model's per-pixel maps (73 measured).
CAMERA_BYTES_PER_PIXEL = 80

#: Bytes per pixel of each frame of the chunk being rendered (27-38 measured).
RENDER_BYTES_PER_PIXEL = 28

#: Bytes per frame of what a run keeps for every frame (series, homographies, sidecar lists).
FRAME_BYTES = 512


def frames_per_chunk(frame_shape: tuple[int, int], at_most: int) -> int:
    """Frames of ``frame_shape`` ``(H, W)`` to render at once: ``at_most``, fewer for frames so
    large that ``at_most`` of them exceed :data:`CHUNK_PIXELS`, at least one."""
    h, w = frame_shape
    return max(1, min(int(at_most), CHUNK_PIXELS // max(1, h * w)))


def working_memory(frame_shape: tuple[int, int], n_frames: int, chunk: int,
                   extra_bytes: float = 0.0) -> float:
    """Bytes a run of ``n_frames`` frames of ``frame_shape`` rendered ``chunk`` at a time needs
    at once (the camera model, a chunk, the per-frame series; ``extra_bytes``: a scene map)."""
    h, w = frame_shape
    pixels = h * w
    return (pixels * (CAMERA_BYTES_PER_PIXEL + chunk * RENDER_BYTES_PER_PIXEL)
            + n_frames * FRAME_BYTES + extra_bytes)
