"""``thermocal info``: what a recording holds, in any format :func:`~thermocal.io.open_recording`
reads (issue 19)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click
import numpy as np

__all__ = ["info", "recording_summary"]


def recording_summary(path: str | Path) -> dict[str, Any]:
    """What a recording holds (one pass over its frames' series and metadata, frames streamed):
    format, frame count and size, bit depth, FPA range and sampling, time span, GPS, the Planck
    constants of its first frame, the frames left out as damaged (those found at open and
    those whose raw image does not decode), and ``beyond_bit_depth`` (the first frame with a
    count the format's bit depth cannot hold, and the largest count) where there is one. JSON
    values."""
    from thermocal._validate import first_frame_outside
    from thermocal.io.open import open_recording

    source = open_recording(path)
    fpa, measured, times, first_meta, gps, attitude, n = [], [], [], None, 0, 0, 0
    spots: list[float] = []
    top, beyond, count_max = 2**source.bit_depth - 1, None, 0
    for chunk in source.iter_frames(skip_undecodable=True):
        k = first_frame_outside(chunk.frames, top) if beyond is None else None
        if k is not None:  # counts the stated bit depth cannot hold: the other commands refuse
            beyond = chunk.start + k
        if chunk.frames.size:
            count_max = max(count_max, int(chunk.frames.max()))
        n += len(chunk)
        if chunk.fpa_c is not None:
            fpa.append(np.asarray(chunk.fpa_c, dtype=np.float64))
            if chunk.fpa_measured is not None:
                measured.append(np.asarray(chunk.fpa_measured, dtype=bool))
        if chunk.time_s is not None:
            times.append(np.asarray(chunk.time_s, dtype=np.float64))
        metas = chunk.metadata or []
        if first_meta is None and metas:
            first_meta = metas[0]
        spots += [float(m["spot_c"]) for m in metas if m.get("spot_c") is not None]
        gps += sum(1 for m in metas if m.get("gps"))
        attitude += sum(1 for m in metas if m.get("attitude"))
    out: dict[str, Any] = {
        "path": str(path), "format": source.format, "frames": n,
        "size": f"{source.frame_shape[1]}x{source.frame_shape[0]}",
        "bit_depth": source.bit_depth, "frames_with_gps": gps, "frames_with_attitude": attitude,
        "damaged_frames": [{"frame": w, "reason": r} for w, r in source.damaged],
        "damaged_summary": source.damaged_summary(),
    }
    if beyond is not None:
        out["beyond_bit_depth"] = {"first_frame": beyond, "count_max": count_max}
    if n == 0:
        from thermocal.io.open import no_frames_error

        raise no_frames_error(source.path, source.damaged)
    if fpa:
        f = np.concatenate(fpa)
        read = int(np.concatenate(measured).sum()) if measured else int(f.size)
        out["fpa_c"] = {"min": float(np.nanmin(f)), "max": float(np.nanmax(f)),
                        "frames_read": read, "resolution_c": source.fpa_resolution_c}
    if spots:  # a DJI XT2/XT-R's FLIR:CentralTemperature: a scene temperature, not the FPA's
        out["spot_c"] = {"min": min(spots), "max": max(spots), "frames": len(spots)}
    if times:
        t = np.concatenate(times)
        out["time_span_s"] = float(t.max() - t.min()) if t.size else 0.0
    if first_meta:
        for key in ("camera_model", "datetime"):
            if first_meta.get(key):
                out[key] = first_meta[key]
        if not first_meta.get("camera_model") and first_meta.get("make"):  # EXIF's (DJI)
            out["camera_model"] = " ".join(
                str(first_meta[k]) for k in ("make", "model") if first_meta.get(k))
        if first_meta.get("planck"):
            out["planck"] = first_meta["planck"]
        if first_meta.get("temperature_range_c"):
            out["temperature_range_c"] = list(first_meta["temperature_range_c"])
    return out


@click.command("info")
@click.argument("path", type=click.Path(path_type=Path))
def info(path: Path) -> None:
    """What a recording holds: format, frames, size, bit depth, FPA range and sampling, time
    span, GPS, Planck constants. PATH: a file or a folder in any format thermocal reads (the
    project's TIFF + JSON, FLIR FFF/SEQ/CSQ, R-JPEG, DualTauUAV, EnvChamberCtrl); or a chamber
    session (HDF5): its frames, set points, FPA range and time span."""
    if _is_chamber(path):
        _chamber_info(path)
        return
    s = recording_summary(path)
    if s["damaged_summary"]:
        click.echo(f"thermocal: warning: {s['damaged_summary']}", err=True)
    click.echo(f"{s['path']}: {s['format']}, {s['frames']} frame(s) of {s['size']}, "
               f"{s['bit_depth']}-bit")
    if "beyond_bit_depth" in s:
        b = s["beyond_bit_depth"]
        click.echo(f"thermocal: warning: counts reach {b['count_max']}, beyond "
                   f"{s['bit_depth']}-bit (from frame {b['first_frame']}): the commands that "
                   "read its frames refuse it; check how it was recorded", err=True)
    if "fpa_c" in s:
        f = s["fpa_c"]
        res = f" (resolution {f['resolution_c']:g} °C)" if f.get("resolution_c") else ""
        click.echo(f"  FPA {f['min']:.2f}…{f['max']:.2f} °C, read at {f['frames_read']} of "
                   f"{s['frames']} frames{res}")
    else:
        click.echo("  no FPA temperature (give --fpa-c to the commands that need it)")
    if "spot_c" in s:
        sp = s["spot_c"]
        click.echo(f"  the camera's spot meter (the centre pixels' temperature, whole °C; "
                   f"FLIR:CentralTemperature) {sp['min']:g}…{sp['max']:g} °C in {sp['frames']} "
                   f"of {s['frames']} frames")
    if "time_span_s" in s:
        click.echo(f"  time span {s['time_span_s']:.3f} s")
    click.echo(f"  GPS in {s['frames_with_gps']} of {s['frames']} frames, attitude in "
               f"{s['frames_with_attitude']}")
    if s["damaged_frames"]:
        listed = ", ".join(f"{d['frame']} ({d['reason']})" for d in s["damaged_frames"])
        click.echo(f"  damaged frames left out: {listed}")
    for key in ("camera_model", "datetime"):
        if key in s:
            click.echo(f"  {key.replace('_', ' ')}: {s[key]}")
    if "temperature_range_c" in s:  # what --method camera vouches for
        lo, hi = s["temperature_range_c"]
        click.echo(f"  the camera's measuring range {lo:g}…{hi:g} °C")
    if "planck" in s:
        p = s["planck"]
        names = ("r1", "r2", "b", "f", "o", "emissivity")
        click.echo("  Planck " + ", ".join(f"{k.upper() if len(k) <= 2 else k} {p[k]:g}"
                                            for k in names if isinstance(p.get(k), int | float)))


def _is_chamber(path: Path) -> bool:
    """Whether ``path`` is an HDF5 chamber session (:func:`~thermocal.io.replaces.hdf5_kind`);
    only a regular file is opened (a FIFO would block; a folder or a missing file: the
    recording readers say what it is)."""
    from thermocal.io.replaces import hdf5_kind

    return Path(path).is_file() and hdf5_kind(path) == "chamber session"


def _chamber_info(path: Path) -> None:
    """``thermocal info`` of a chamber session: what `thermocal calibrate` would fit on."""
    from thermocal.io.chamber import read_chamber

    s = read_chamber(path, frames=False)  # validated; its frames left on disk
    h, w = s.frame_shape
    points = np.unique(np.round(s.blackbody_c, 3))
    click.echo(f"{path}: a chamber session (HDF5), {s.n_frames} frame(s) of {w}x{h}, "
               f"{s.bit_depth}-bit; `thermocal calibrate` reads it")
    click.echo(f"  blackbody {points.min():g}…{points.max():g} °C at {points.size} set point(s)")
    click.echo(f"  FPA {float(np.min(s.fpa_c)):.2f}…{float(np.max(s.fpa_c)):.2f} °C")
    click.echo(f"  time span {float(np.ptp(s.time_s)):.0f} s")
    camera = ", ".join(f"{k} {s.attrs[k]}" for k in ("preset", "unit") if k in s.attrs)
    if camera:
        click.echo(f"  camera: {camera}")
