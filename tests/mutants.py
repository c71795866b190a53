"""Byte-level mutants of a file, shared by the fuzz tests of the readers."""

from __future__ import annotations


def flip_bytes(data: bytes, rng) -> bytes:
    """``data`` damaged once, at random (``rng``): bits flipped, cut, a block zeroed, a byte
    set, or a block copied over another."""
    b = bytearray(data)
    kind = rng.integers(5)
    if kind == 0:  # flip bits of 1…8 bytes anywhere
        for pos in rng.integers(0, len(b), rng.integers(1, 9)):
            b[pos] ^= int(rng.integers(1, 256))
    elif kind == 1:  # truncate
        del b[int(rng.integers(0, len(b))):]
    elif kind == 2:  # zero a block
        pos, n = int(rng.integers(0, len(b))), int(rng.integers(4, 257))
        b[pos:pos + n] = bytes(len(b[pos:pos + n]))
    elif kind == 3:  # one byte set to a random value
        b[int(rng.integers(0, len(b)))] = int(rng.integers(0, 256))
    else:  # a block moved elsewhere (overwriting)
        n = int(rng.integers(4, 129))
        src, dst = (int(v) for v in rng.integers(0, max(len(b) - n, 1), 2))
        b[dst:dst + n] = b[src:src + n]
    return bytes(b)


def change_element(a, rng, replacements):
    """A copy of array ``a`` with one element, drawn at random, changed: a bool flipped, else
    replaced by one of ``replacements(v)`` (the element's value ``v`` as a float → candidate
    values), cast to ``a``'s dtype."""
    import numpy as np

    a = np.array(a)
    if a.size == 0:
        return a
    idx = tuple(int(rng.integers(n)) for n in a.shape)
    if a.dtype == bool:
        a[idx] = not a[idx]
        return a
    v = float(a[idx])
    with np.errstate(all="ignore"):
        new = replacements(v)
        a[idx] = np.asarray(new[int(rng.integers(len(new)))]).astype(a.dtype)
    return a
