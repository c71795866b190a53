"""Fuzzed input files: recordings, chamber files (HDF5 and EnvChamberCtrl .npz) and real scenes.

Issue 18, item 6: the file readers that had no fuzz tests get the treatment of
``tests/test_model_files.py``. Each mutant of a small valid file (bytes flipped, the file
truncated, a block zeroed or moved; or a structure-level change: a sidecar value, the TIFF's
pages, shape or dtype, an HDF5 dataset or attribute, an .npz array) must either

* load and give the original's data (SAME),
* load and give other data that are finite and whose use downstream (``check_burst`` on the
  frames) passes or raises a :class:`~thermocal.errors.ThermocalError` (DIFFERENT: none of
  these files holds a checksum, so a changed count is not damage a reader can see), or
* be refused with a one-line :class:`~thermocal.errors.ThermocalError` (REFUSED),

never another exception, a hang or NaN data.
"""

from __future__ import annotations

import contextlib
import io
import json
import signal
import warnings
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
import tifffile
from mutants import change_element
from mutants import flip_bytes as _flip_bytes

from thermocal.burst import check_burst
from thermocal.camera.presets import make_camera
from thermocal.errors import ThermocalError
from thermocal.io.chamber import (
    ChamberSession,
    iter_chamber_frames,
    read_chamber,
    write_chamber,
)
from thermocal.io.envchamber import import_envchamberctrl_npz
from thermocal.io.recording import (
    Recording,
    iter_recording,
    read_recording,
    read_recording_header,
    write_recording,
)
from thermocal.scenes.real import list_shared_scenes, load_scene
from thermocal.simulate.chamber import ChamberPlan, simulate_chamber

SAME, REFUSED, DIFFERENT = "same", "refused", "different"
#: Seconds a mutant may take to be read (a hang is a failure).
TIME_GUARD_S = 10


# ---------------------------------------------------------------------------- byte mutants


def _flip_header_bytes(data: bytes, rng, head: int = 4096) -> bytes:
    """Byte mutants aimed at the first ``head`` bytes, where the structure lives."""
    b = bytearray(data)
    for pos in rng.integers(0, min(head, len(b)), rng.integers(1, 5)):
        b[pos] ^= int(rng.integers(1, 256))
    return bytes(b)


def _new_value(value, rng):
    """A random replacement of a JSON-like value: nearby, far, of another type, nested."""
    choices = [None, "text", [], {}, True, float("nan"), float("inf"), -1, 0, 10**6, 1e300,
               10**400, [[1.0, 2.0]], {"a": 1}]
    if isinstance(value, bool):
        choices += [not value]
    elif isinstance(value, (int, float)):
        choices += [value + 1, value - 1, -value, value * 2]
        if abs(value) < 1e300:
            choices += [float(value)]
    elif isinstance(value, list):
        choices += [value[:-1], value[::-1], [*value, value[0] if value else 0],
                    [*value[:-1], float("nan")], [*value[:-1], "20"], [*value[:-1], [1.0]],
                    [*value[:-1], 1e308 * 10], [*value[:-1], 10**400], [*value[:-1], None],
                    [*value[:-1], -300.0], [*value[:-1], True]]
    elif isinstance(value, str):
        choices += [value[:-1], value.upper(), ""]
    return choices[int(rng.integers(len(choices)))]


def _change_element(a: np.ndarray, rng) -> np.ndarray:
    return change_element(a, rng, lambda v: [v + 1, 0.0, -v, np.nan, np.inf, -np.inf, 1e30,
                                             v * 1.5, 65535, -300.0])


# ---------------------------------------------------------------------------- outcomes


class _Hang(Exception):
    pass


@contextlib.contextmanager
def _time_guard(seconds: int):
    def alarm(signum, frame):
        raise _Hang(f"took more than {seconds} s")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _same(got: dict, want: dict) -> bool:
    if got.keys() != want.keys():
        return False
    for k, w in want.items():
        g = got[k]
        if isinstance(w, np.ndarray):
            if not (isinstance(g, np.ndarray) and g.shape == w.shape and g.dtype == w.dtype
                    and np.array_equal(g, w)):
                return False
        elif g != w:
            return False
    return True


def _usable(got: dict) -> str | None:
    """None if the data read are finite and ``check_burst`` passes or refuses them cleanly."""
    for k, v in got.items():
        if isinstance(v, np.ndarray) and v.dtype.kind == "f" and not np.all(np.isfinite(v)):
            return f"{k} holds NaN or infinite values"
    frames = got.get("frames")
    if frames is not None and frames.ndim == 3 and frames.shape[0] >= 1:
        try:
            check_burst(frames, bit_depth=int(got.get("bit_depth", 14)))
        except ThermocalError:
            pass
    return None


def _outcome(path: Path, read: Callable[[Path], dict], want: dict) -> str:
    try:
        with _time_guard(TIME_GUARD_S), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            got = read(path)
            if _same(got, want):
                return SAME
            bad = _usable(got)
    except ThermocalError as exc:
        message = str(exc)
        if "\n" in message or not message:
            return f"refused with a bad message: {message!r}"
        return REFUSED
    except Exception as exc:  # the failure this test is for (a hang included)
        return f"{type(exc).__name__}: {str(exc)[:200]}"
    return f"accepted: {bad}" if bad else DIFFERENT


def _tally(outcomes: list[tuple[str, str]], n: int) -> dict[str, int]:
    counts: dict[str, int] = {}
    bad = []
    for how, result in outcomes:
        key = result if result in (SAME, REFUSED, DIFFERENT) else "wrong"
        counts[key] = counts.get(key, 0) + 1
        if key == "wrong":
            bad.append(f"{how}: {result}")
    assert not bad, f"{len(bad)} of {n} mutants: " + "; ".join(bad[:10])
    assert sum(counts.values()) == n, counts
    return counts


# ---------------------------------------------------------------------------- recordings

FRAMES_N, H, W = 7, 24, 32


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    rng = np.random.default_rng(6)
    folder = tmp_path_factory.mktemp("rec")
    frames = rng.integers(6000, 9000, (FRAMES_N, H, W)).astype(np.uint16)
    rec = Recording(frames, fpa_c=np.linspace(30.0, 31.0, FRAMES_N),
                    time_s=np.arange(FRAMES_N) / 9.0, housing_c=[35.0] * FRAMES_N,
                    extra={"pivot": 3})
    write_recording(folder / "rec.tiff", rec)
    return folder / "rec.tiff"


def read_recording_all(path: Path) -> dict:
    """The recording read three ways (header, whole, iterated), which must agree."""
    header = read_recording_header(path)
    rec = read_recording(path)
    blocks = [b for _, b in iter_recording(path, chunk=3)]
    it = np.concatenate(blocks) if blocks else np.zeros((0, H, W), np.uint16)
    assert header.n_frames == rec.n_frames and header.frame_shape == rec.frame_shape
    assert np.array_equal(it, rec.frames), "iter_recording and read_recording disagree"
    out = {"frames": np.asarray(rec.frames), "bit_depth": rec.bit_depth,
           "extra": rec.extra}
    for key in ("fpa_c", "time_s", "housing_c", "ambient_c"):
        value = getattr(rec, key)
        out[key] = None if value is None else np.asarray(value)
    return out


def _mutate_sidecar(json_path: Path, rng) -> None:
    side = json.loads(json_path.read_text())
    if not isinstance(side, dict):
        return
    keys = sorted(side)
    key = keys[int(rng.integers(len(keys)))]
    op = int(rng.integers(5))
    if op == 0:
        del side[key]
    elif op == 1 and isinstance(side[key], list) and side[key]:
        i = int(rng.integers(len(side[key])))
        side[key][i] = _new_value(side[key][i], rng)
    else:
        side[key] = _new_value(side[key], rng)
    text = json.dumps(side)  # NaN, Infinity and 1e999 as Python's json writes them
    if rng.integers(6) == 0:
        text = text.replace("]", "", 1) if rng.integers(2) else "[" + text + "]"
    json_path.write_text(text)


def _mutate_tiff_structure(path: Path, frames: np.ndarray, rng) -> None:
    op = int(rng.integers(9))
    data = {0: lambda: frames[:-1], 1: lambda: frames[:1], 2: lambda: np.concatenate(
        [frames, frames[:2]]), 3: lambda: frames[:, :-1], 4: lambda: frames.astype(np.float32),
        5: lambda: frames.astype(np.int16), 6: lambda: frames.astype(np.uint32),
        7: lambda: np.full_like(frames, 65535), 8: lambda: frames[0]}[op]()
    kwargs = {}
    if rng.integers(3) == 0:
        kwargs["compression"] = "zlib"
    tifffile.imwrite(path, data, **kwargs)


def fuzz_recording(source: Path, n: int, seed: int, folder: Path) -> dict[str, int]:
    rng = np.random.default_rng(seed)
    want = read_recording_all(source)
    tiff_bytes = source.read_bytes()
    json_bytes = source.with_suffix(".json").read_bytes()
    outcomes = []
    for i in range(n):
        path = folder / f"m{i}.tiff"
        side = path.with_suffix(".json")
        path.write_bytes(tiff_bytes)
        side.write_bytes(json_bytes)
        kind = i % 4
        if kind == 0:
            how = "tiff bytes"
            path.write_bytes(_flip_bytes(tiff_bytes, rng) if rng.integers(2)
                             else _flip_header_bytes(tiff_bytes, rng, 512))
        elif kind == 1:
            how = "json bytes"
            side.write_bytes(_flip_bytes(json_bytes, rng))
        elif kind == 2:
            how = "sidecar"
            for _ in range(1 if rng.integers(3) else 2):
                with contextlib.suppress(ValueError, TypeError):  # the first broke the JSON
                    _mutate_sidecar(side, rng)
        else:
            how = "tiff structure"
            _mutate_tiff_structure(path, want["frames"], rng)
            if rng.integers(4) == 0:
                side.unlink()
        outcomes.append((f"mutant {i} ({how})", _outcome(path, read_recording_all, want)))
        path.unlink()
        side.unlink(missing_ok=True)
    return _tally(outcomes, n)


# ---------------------------------------------------------------------------- chamber files


@pytest.fixture(scope="module")
def chamber_session() -> ChamberSession:
    camera = make_camera("tau2", unit=0, size=(W, H))
    plan = ChamberPlan(setpoints_c=(15.0, 45.0), frames_per_point=2, profile="steps",
                       ambient_c=(10.0, 30.0), interval_s=10.0, duration_s=80.0)
    parts = list(simulate_chamber(camera, plan, seed=2))
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in (
        "frames", "blackbody_c", "fpa_c", "time_s", "housing_c", "ambient_c")}
    return ChamberSession(cat.pop("frames"), **cat, attrs={"unit": 0, "preset": "tau2"})


@pytest.fixture(scope="module")
def chamber_file(chamber_session, tmp_path_factory) -> Path:
    return write_chamber(tmp_path_factory.mktemp("ch") / "chamber.h5", chamber_session)


def _session_dict(s: ChamberSession) -> dict:
    out = {"frames": np.asarray(s.frames), "bit_depth": s.bit_depth,
           "attrs": json.dumps(s.attrs, sort_keys=True, default=str)}
    for key in ("blackbody_c", "fpa_c", "time_s", "housing_c", "ambient_c"):
        value = getattr(s, key)
        out[key] = None if value is None else np.asarray(value)
    return out


def read_chamber_all(path: Path) -> dict:
    """The chamber file read whole, lazily and iterated, which must agree."""
    s = read_chamber(path)
    lazy = read_chamber(path, frames=False)
    blocks = [b for _, b in iter_chamber_frames(path, chunk=3)]
    assert np.array_equal(np.concatenate(blocks), s.frames), "iter and read disagree"
    assert np.array_equal(np.asarray(lazy.frames), s.frames), "lazy and read disagree"
    return _session_dict(s)


def _mutate_chamber_h5(path: Path, rng) -> None:
    with h5py.File(path, "a") as f:
        names = sorted(f)
        kind = rng.choice(["element", "element", "dataset", "dataset", "attr", "attr"])
        name = names[int(rng.integers(len(names)))]
        if kind == "element":
            f[name][...] = _change_element(f[name][()], rng)
        elif kind == "dataset":
            a = f[name][()]
            op = int(rng.integers(9))
            del f[name]
            if op == 0:
                return  # deleted
            new = {1: lambda: a.T, 2: lambda: a[..., :-1], 3: lambda: a.astype(np.float64),
                   4: lambda: np.asarray(a).astype("S8"), 5: lambda: a[None],
                   6: lambda: a.ravel(), 7: lambda: a.astype(np.int32),
                   8: lambda: a[:0]}[op]()
            f.create_dataset(name, data=new)
            if op == 1 and rng.integers(2):  # a group where a dataset was
                del f[name]
                f.create_group(name)
        else:
            attrs = sorted(f.attrs)
            key = attrs[int(rng.integers(len(attrs)))]
            old = f.attrs[key]
            op = int(rng.integers(5))
            if op == 0:
                del f.attrs[key]
            elif op == 1:
                f.attrs[key] = h5py.Empty("f8")
            elif op == 2 and np.asarray(old).dtype.kind in "iuf":
                f.attrs[key] = _change_element(np.asarray(old), rng)
            elif op == 3:
                f.attrs[key] = [1, 2, 3][: int(rng.integers(1, 4))]
            else:
                value = _new_value(old.item() if isinstance(old, np.generic) else
                                   (old.tolist() if isinstance(old, np.ndarray) else old), rng)
                with contextlib.suppress(TypeError, ValueError):
                    f.attrs[key] = value if value is not None else h5py.Empty("i8")


def _fuzz_bytes_or_structure(source: Path, read, mutate, n: int, seed: int,
                             folder: Path) -> dict[str, int]:
    rng = np.random.default_rng(seed)
    want = read(source)
    data = source.read_bytes()
    outcomes = []
    for i in range(n):
        path = folder / f"m{i}{source.suffix}"
        if i % 2 == 0:
            how = "bytes"
            path.write_bytes(_flip_bytes(data, rng) if i % 4 == 0
                             else _flip_header_bytes(data, rng))
        else:
            how = "structure"
            path.write_bytes(data)
            for _ in range(1 if rng.integers(3) else 2):
                with contextlib.suppress(Exception):  # a change the first made impossible
                    mutate(path, rng)
        outcomes.append((f"mutant {i} ({how})", _outcome(path, read, want)))
        path.unlink()
    return _tally(outcomes, n)


@pytest.fixture(scope="module")
def npz_file(chamber_session, tmp_path_factory) -> Path:
    s = chamber_session
    path = tmp_path_factory.mktemp("npz") / "session.npz"
    t0 = 1_700_000_000_000_000_000
    np.savez(path, frames=np.asarray(s.frames),
             fpa=np.round(s.fpa_c * 100).astype(np.uint16),
             housing=np.round(s.housing_c * 100).astype(np.uint16),
             blackbody=np.round(s.blackbody_c * 100).astype(np.uint16),
             time_ns=(t0 + np.round(s.time_s * 1e9)).astype(np.int64))
    return path


def read_npz(path: Path) -> dict:
    return _session_dict(import_envchamberctrl_npz(path))


def _mutate_npz(path: Path, rng) -> None:
    with np.load(path, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    key = sorted(arrays)[int(rng.integers(len(arrays)))]
    a = arrays[key]
    op = int(rng.integers(10))
    if op == 0:
        del arrays[key]
    elif op == 1:
        arrays[key] = a.astype(np.float64)
    elif op == 2:
        arrays[key] = a.astype(np.float64) * np.nan
    elif op == 3:
        arrays[key] = a[:-1]
    elif op == 4:
        arrays[key] = a[None]
    elif op == 5:
        arrays[key] = a.astype("S8")
    elif op == 6:
        arrays[key] = a[:0]
    elif op == 7:
        with np.errstate(all="ignore"):
            arrays[key] = a.astype(np.int8)
    elif op == 8:
        arrays[key + "_x"] = a
        del arrays[key]
    else:
        arrays[key] = _change_element(a, rng)
    buf = io.BytesIO()
    np.savez(buf, **arrays) if rng.integers(2) else np.savez_compressed(buf, **arrays)
    path.write_bytes(buf.getvalue())


# ---------------------------------------------------------------------------- scenes


def _scene_sources() -> list[Path]:
    scenes = list_shared_scenes()
    want = ["15_linear_load", "01_200_deg_neutral", "frame_000000"]
    return [scenes[k] for k in want if k in scenes]


@pytest.fixture(scope="module")
def scene_files(tmp_path_factory) -> list[Path]:
    """The smallest shipped R-JPEG, another, the FFF, and a small radiometric TIFF cut from the
    shipped flirpy TIFF (a full one decodes in 20 ms: too slow for 1000 mutants)."""
    sources = _scene_sources()
    if not sources:
        pytest.skip("no shared scenes")
    folder = tmp_path_factory.mktemp("scenes")
    scenes = list_shared_scenes()
    if "example_radiometric" in scenes:
        counts = tifffile.imread(scenes["example_radiometric"])[200:248, 300:364]
        tifffile.imwrite(folder / "crop.tiff", counts, compression="lzw")
        sources.append(folder / "crop.tiff")
    return sources


def read_scene(path: Path) -> dict:
    return {"map": load_scene(path)}


def fuzz_scenes(sources: list[Path], n: int, seed: int, folder: Path) -> dict[str, int]:
    rng = np.random.default_rng(seed)
    outcomes = []
    wants = [read_scene(s) for s in sources]
    datas = [s.read_bytes() for s in sources]
    for i in range(n):
        j = i % len(sources)
        path = folder / f"m{i}{sources[j].suffix}"
        if i % 3 == 0:
            how = "bytes"
            path.write_bytes(_flip_bytes(datas[j], rng))
        else:  # the headers: the FLIR APP1 segments, the TIFF's IFD, the FFF's records
            how = "header bytes"
            path.write_bytes(_flip_header_bytes(datas[j], rng, 2048 if i % 3 == 1 else 512))
        outcomes.append((f"mutant {i} ({sources[j].name}, {how})",
                         _outcome(path, read_scene, wants[j])))
        path.unlink()
    return _tally(outcomes, n)


# ---------------------------------------------------------------------------- the tests


def _run(reader, n, seed, recording, chamber_file, npz_file, scene_files, folder):
    if reader == "recording":
        counts = fuzz_recording(recording, n, seed, folder)
    elif reader == "chamber-h5":
        counts = _fuzz_bytes_or_structure(chamber_file, read_chamber_all, _mutate_chamber_h5,
                                          n, seed, folder)
    elif reader == "chamber-npz":
        counts = _fuzz_bytes_or_structure(npz_file, read_npz, _mutate_npz, n, seed, folder)
    else:
        counts = fuzz_scenes(scene_files, n, seed, folder)
    print(f"{reader}: {counts}")
    assert counts.get(REFUSED, 0) > n // 10, counts
    return counts


READERS = ["recording", "chamber-h5", "chamber-npz", "scene"]


@pytest.fixture
def all_files(request):
    names = ("recording", "chamber_file", "npz_file", "scene_files")
    reader = request.node.callspec.params["reader"]
    need = dict(zip(READERS, names, strict=True))[reader]
    return {n: (request.getfixturevalue(n) if n == need else None) for n in names}


@pytest.mark.parametrize("reader", READERS)
def test_fuzzed_input_files_are_read_unchanged_or_refused(reader, all_files, tmp_path):
    _run(reader, 200, 18, **all_files, folder=tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("reader", READERS)
def test_fuzzed_input_files_at_length(reader, all_files, tmp_path):
    _run(reader, 1000, 1806, **all_files, folder=tmp_path)


# ---------------------------------------------------------------------------- regression cases


def test_a_chamber_file_with_a_damaged_hdf5_header_is_refused_not_allocated(chamber_file,
                                                                           tmp_path):
    """A byte mutant (chamber-h5) whose header declared a series of 3.6e9 values: the reader
    allocated 27 GiB (MemoryError) before it found the length wrong; now refused unread."""
    path = tmp_path / "huge.h5"
    path.write_bytes(chamber_file.read_bytes())
    with h5py.File(path, "a") as f:
        del f["housing_c"]
        f.create_dataset("housing_c", shape=(2**31,), dtype="f8")  # declared, never written
    with pytest.raises(ThermocalError) as info:
        read_chamber(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    assert any("more than the file holds" in p for p in info.value.problems)


def _read_chamber_in_subprocess(path):
    """Read a chamber file in a fresh interpreter (a hang or a crash of libhdf5 cannot take the
    test run with it): exit status 3 when it is refused with a ThermocalError."""
    import subprocess
    import sys

    code = ("import sys; from thermocal.io.chamber import read_chamber\n"
            "from thermocal.errors import ThermocalError\n"
            "try:\n    read_chamber(sys.argv[1])\nexcept ThermocalError:\n    sys.exit(3)\n")
    return subprocess.run([sys.executable, "-c", code, str(path)], timeout=5,
                          capture_output=True)


@pytest.mark.parametrize("name", ["token", "zipver"])
def test_an_npz_that_numpy_cannot_parse_is_refused(npz_file, tmp_path, name):
    """Byte mutants of an EnvChamberCtrl .npz that raised tokenize.TokenError (a .npy header
    cut in its dict) and NotImplementedError (a zip 'version needed' of 20.4)."""
    import zipfile

    path = tmp_path / f"{name}.npz"
    if name == "token":
        with zipfile.ZipFile(path, "w") as z:
            z.writestr("frames.npy", b"\x93NUMPY\x01\x00\x76\x00{'descr': '<u2', 'fortran_order'"
                       + b" " * 70 + b"\n")
            for key in ("fpa", "blackbody", "time_ns"):
                z.writestr(f"{key}.npy", b"")
    else:
        raw = bytearray(npz_file.read_bytes())
        raw[4] = 204  # the first local header's "version needed to extract": 20.4
        raw[raw.rfind(b"PK\x01\x02") + 6] = 204  # and its central directory entry's
        path.write_bytes(bytes(raw))
    with pytest.raises(ThermocalError) as info:
        import_envchamberctrl_npz(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_chamber_file_with_a_damaged_global_heap_does_not_hang(chamber_file, tmp_path):
    """A byte mutant (chamber-h5, seeds 101 and 102): one byte of the size of the global heap's
    second object (the 'preset' string) changed; libhdf5 never returned from reading the
    'format' attribute. Now refused before h5py opens the file (run in a subprocess, so that a
    hang fails the test instead of stopping the run)."""
    raw = bytearray(chamber_file.read_bytes())
    gcol = raw.find(b"GCOL")
    assert gcol > 0
    raw[gcol + 65] = 0x0A  # object 2's size: 4 → 2564 bytes, beyond the collection
    path = tmp_path / "heap.h5"
    path.write_bytes(bytes(raw))
    proc = _read_chamber_in_subprocess(path)
    assert proc.returncode == 3, proc.stderr[-500:]


@pytest.mark.parametrize("value", [0xFA, 2])
def test_a_chamber_file_with_a_damaged_heap_reference_does_not_crash(chamber_file, tmp_path,
                                                                     value):
    """A byte mutant (chamber-h5, seed 101): the type bits of the variable-length string
    attribute 'format' set from 1 (a string) to 250 or 2 (no valid variable-length type):
    libhdf5 then kills the interpreter reading it. Refused by its type, before it is read."""
    raw = bytearray(chamber_file.read_bytes())
    at = raw.find(b"GCOL") - 47
    if raw[at] != 1:
        pytest.skip("another HDF5 layout: the damaged byte is elsewhere")
    raw[at] = value
    path = tmp_path / "ref.h5"
    path.write_bytes(bytes(raw))
    proc = _read_chamber_in_subprocess(path)
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-300:])


# ---------------------------------------------------------------------------- FLIR, DualTauUAV
# (issue 19): the formats of open_recording, whose damaged frames are left out rather than the
# whole recording refused: a mutant reads the same, reads fewer or other frames (finite, named
# in ``damaged``), or is refused in one line; streamed (open_stream) it gives the frames it
# counted or stops with one line.


def read_any(path: Path) -> dict:
    from thermocal.io.open import open_recording, open_stream

    source = open_recording(path)
    rec = source.read_all()
    assert len(rec.frames) + len(source.damaged) >= 1
    try:
        header = open_stream(path)
        streamed = sum(len(f) for _, f in header.chunks(3))
        assert streamed == header.n_frames, "open_stream gave another count than it said"
    except ThermocalError as exc:
        assert "\n" not in str(exc), str(exc)
    return {"frames": np.asarray(rec.frames),
            "fpa_c": None if rec.fpa_c is None else np.asarray(rec.fpa_c),
            "time_s": None if rec.time_s is None else np.asarray(rec.time_s),
            "bit_depth": rec.bit_depth}


@pytest.fixture(scope="module")
def flir_files(tmp_path_factory) -> dict[str, Path]:
    from test_open_recording import _dji_xmp, _dualtau_file, _fff, _frames, _rjpeg

    folder = tmp_path_factory.mktemp("flir")
    frames = _frames(4, h=H, w=W, seed=7)
    (folder / "f.seq").write_bytes(b"".join(_fff(fr, ms=40 * k) for k, fr in enumerate(frames)))
    (folder / "f.csq").write_bytes(b"".join(_fff(fr, codec="jpegls", ms=40 * k)
                                            for k, fr in enumerate(frames)))
    (folder / "f.jpg").write_bytes(_rjpeg(_fff(frames[0], codec="jpegls"), parts=2,
                                          xmp=_dji_xmp(30)))
    _dualtau_file(folder / "f.npz", frames, np.full(4, 3010), 1_700_000_000_000_000_000)
    return {p.suffix[1:]: p for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("kind", ["seq", "csq", "jpg", "npz"])
def test_fuzzed_flir_and_dualtau_files_are_read_unchanged_fewer_or_refused(flir_files, kind,
                                                                          tmp_path):
    source = flir_files[kind]
    rng = np.random.default_rng(19)
    want = read_any(source)
    data = source.read_bytes()
    outcomes = []
    for i in range(150):
        path = tmp_path / f"m{i}{source.suffix}"
        path.write_bytes(_flip_bytes(data, rng) if i % 2 else _flip_header_bytes(data, rng))
        outcomes.append((f"mutant {i}", _outcome(path, read_any, want)))
        path.unlink()
    counts = _tally(outcomes, 150)
    print(f"{kind}: {counts}")
    assert counts.get(REFUSED, 0) + counts.get(DIFFERENT, 0) > 15, counts
