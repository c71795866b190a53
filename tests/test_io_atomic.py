"""Tests for thermocal.io.atomic: outputs are complete and in place, or not there at all."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from thermocal.errors import InvalidInputError, ThermocalError
from thermocal.io.atomic import atomic_path, ensure_output_dir, write_json_atomic


class Boom(Exception):
    """A failure inside a write block."""


def _names(directory):
    return sorted(p.name for p in directory.iterdir())


def test_atomic_path_success_renames_onto_target(tmp_path):
    target = tmp_path / "frames.tiff"
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path
        assert tmp.name.startswith(".")
        assert tmp.name.endswith(".tiff")
        assert tmp != target
        assert tmp.exists()
        assert not target.exists()
        tmp.write_bytes(b"data")
    assert target.read_bytes() == b"data"
    assert _names(tmp_path) == ["frames.tiff"]


def test_atomic_path_temp_name_ends_like_a_suffixless_target(tmp_path):
    with atomic_path(tmp_path / "pivot") as tmp:
        assert tmp.name.startswith(".pivot.")
        tmp.write_text("x")
    assert _names(tmp_path) == ["pivot"]


def test_atomic_path_failure_leaves_nothing(tmp_path):
    target = tmp_path / "out.h5"
    with pytest.raises(Boom), atomic_path(target) as tmp:
        tmp.write_bytes(b"half written")
        raise Boom
    assert _names(tmp_path) == []


def test_atomic_path_failure_keeps_existing_output(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("good")
    with pytest.raises(Boom), atomic_path(target) as tmp:
        tmp.write_text("bad")
        raise Boom
    assert target.read_text() == "good"
    assert _names(tmp_path) == ["out.json"]


def test_atomic_path_keyboard_interrupt_cleans_up(tmp_path):
    with pytest.raises(KeyboardInterrupt), atomic_path(tmp_path / "a.tiff") as tmp:
        tmp.write_bytes(b"x")
        raise KeyboardInterrupt
    assert _names(tmp_path) == []


def test_atomic_path_replaces_existing_on_success(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with atomic_path(target, fsync=True) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new"
    assert _names(tmp_path) == ["out.txt"]


def test_atomic_path_mode_follows_umask(tmp_path):
    old = os.umask(0o022)
    try:
        with atomic_path(tmp_path / "m.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    assert (tmp_path / "m.txt").stat().st_mode & 0o777 == 0o644


def test_atomic_path_missing_directory(tmp_path):
    with (
        pytest.raises(InvalidInputError, match="does not exist"),
        atomic_path(tmp_path / "nope" / "x.tiff"),
    ):
        pass  # pragma: no cover


def test_atomic_path_target_is_directory(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(InvalidInputError, match="is a directory"), atomic_path(tmp_path / "d"):
        pass  # pragma: no cover


def test_atomic_path_vanished_temp(tmp_path):
    with pytest.raises(ThermocalError, match="vanished"), atomic_path(tmp_path / "x.json") as tmp:
        tmp.unlink()
    assert _names(tmp_path) == []


def test_write_json_atomic_round_trip_with_numpy(tmp_path):
    obj = {"fpa_c": np.array([20.5, 21.0]), "pivot": np.int64(3), "ok": True, "name": "x"}
    out = write_json_atomic(tmp_path / "meta.json", obj)
    assert out == tmp_path / "meta.json"
    text = out.read_text(encoding="utf-8")
    assert text.endswith("\n")
    assert json.loads(text) == {"fpa_c": [20.5, 21.0], "pivot": 3, "ok": True, "name": "x"}


def test_write_json_atomic_rejects_nan_and_keeps_old(tmp_path):
    target = tmp_path / "meta.json"
    target.write_text('{"old": 1}')
    with pytest.raises(InvalidInputError, match="NaN"):
        write_json_atomic(target, {"x": [1.0, float("nan")]})
    assert json.loads(target.read_text()) == {"old": 1}
    assert _names(tmp_path) == ["meta.json"]


def test_write_json_atomic_rejects_unserialisable(tmp_path):
    with pytest.raises(InvalidInputError):
        write_json_atomic(tmp_path / "m.json", {"x": object()})
    assert _names(tmp_path) == []


def test_ensure_output_dir_creates_parents(tmp_path):
    out = ensure_output_dir(tmp_path / "a" / "b" / "c")
    assert out.is_dir()
    assert ensure_output_dir(out) == out  # existing directory is fine


def test_ensure_output_dir_rejects_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(InvalidInputError, match="is a file"):
        ensure_output_dir(f)


def test_ensure_output_dir_rejects_unwritable(tmp_path, monkeypatch):
    monkeypatch.setattr(os, "access", lambda *args, **kwargs: False)
    with pytest.raises(InvalidInputError, match="not writable"):
        ensure_output_dir(tmp_path / "out")


def test_ensure_output_dir_below_a_file(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(InvalidInputError, match="cannot create"):
        ensure_output_dir(f / "sub")


def test_temp_name_pattern_matches_the_names_atomic_path_gives(tmp_path):
    from thermocal.io.atomic import atomic_path, temp_name_pattern

    for target, stem in (("frame_000003.tiff", r"frame_\d{6,}"), ("log.csv", "log")):
        with atomic_path(tmp_path / target) as tmp:
            tmp.write_bytes(b"x")
            suffix = "." + target.rsplit(".", 1)[1]
            assert temp_name_pattern(stem, suffix).fullmatch(tmp.name), tmp.name
            assert not temp_name_pattern(stem, suffix).fullmatch(target)
