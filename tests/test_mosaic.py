"""thermocal mosaic: known-answer tests on synthetic flight outputs (crops of a known scene at
known offsets, with noise), and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
import tifffile
from click.testing import CliRunner
from scipy.ndimage import gaussian_filter

from thermocal.errors import InvalidInputError
from thermocal.io.recording import write_sigma_tiff, write_temperature_tiff
from thermocal.pipeline.commands import mosaic as mosaic_command
from thermocal.pipeline.mosaic import build_mosaic

MAP = (80, 112)  # (H, W) of a map
STEP = (9, 1)  # (dx, dy) pixels between consecutive maps
NOISE_C = 0.05
SIGMA_C = 0.3


def _scene(shape=(140, 260), seed=0):
    """A textured scene, °C: smooth noise of about 3 °C around 25 °C."""
    field = gaussian_filter(np.random.default_rng(seed).normal(size=shape), 3.0)
    return (25.0 + 3.0 * field / field.std()).astype(np.float64)


def _flight_out(path, scene, n_maps, *, seed=1, stride=7, bad=None, sigma=True, offset_c=5.0):
    """A flight output: maps of ``scene`` at ``(k*STEP + (4, 4))``, noise ``NOISE_C``, one log
    line per pivot; map ``bad`` offset by ``offset_c``. Returns the map origins (x, y)."""
    rng = np.random.default_rng(seed)
    (path / "temps").mkdir(parents=True)
    origins, lines = [], []
    for k in range(n_maps):
        x, y = 4 + STEP[0] * k, 4 + STEP[1] * k
        temp = scene[y : y + MAP[0], x : x + MAP[1]] + rng.normal(0, NOISE_C, MAP)
        if k == bad:
            temp = temp + offset_c
        frame = 3 + stride * k
        write_temperature_tiff(path / "temps" / f"frame_{frame:06d}.tiff", temp)
        if sigma:
            write_sigma_tiff(path / "temps" / f"frame_{frame:06d}_sigma.tiff",
                             np.full(MAP, SIGMA_C + 0.01 * k))
        origins.append((x, y))
        lines.append(json.dumps({"frame": frame, "mean_c": float(temp.mean())}))
    (path / "log.jsonl").write_text("\n".join(lines) + "\n")
    return origins


def _layers(out):
    return {name: tifffile.imread(out / "mosaic" / f"{name}.tiff")
            for name in ("temperature", "views", "spread", "sigma")
            if (out / "mosaic" / f"{name}.tiff").exists()}


def _truth_views(origins, canvas_shape, offset, grow):
    """Views per canvas pixel for maps at known origins (the first one at ``offset``), their
    footprints grown by ``grow`` pixels on every side (negative: shrunk)."""
    views = np.zeros(canvas_shape, int)
    x_first, y_first = origins[0]
    for x, y in origins:
        cx, cy = x - x_first + int(round(offset[0])), y - y_first + int(round(offset[1]))
        views[max(0, cy - grow) : cy + MAP[0] + grow, max(0, cx - grow) : cx + MAP[1] + grow] += 1
    return views


@pytest.fixture(scope="module")
def scene():
    return _scene()


def test_canvas_recovers_the_scene(scene, tmp_path):
    origins = _flight_out(tmp_path, scene, 12)
    summary = build_mosaic(tmp_path)
    layers = _layers(tmp_path)
    canvas = summary["canvas"]
    assert len(summary["maps_used"]) == 12 and summary["maps_left_out"] == []
    assert (canvas["height"], canvas["width"]) == layers["temperature"].shape
    # the first map sits at offset_px; registration recovers the translations
    for m, (x, y) in zip(summary["maps_used"], origins, strict=True):
        h = np.array(m["to_canvas"])
        expect = np.array(canvas["offset_px"]) + (x - origins[0][0], y - origins[0][1])
        assert np.allclose(h[:2, 2], expect, atol=0.15)
        assert np.allclose(h[:2, :2], np.eye(2), atol=0.005)
    ox, oy = (int(round(v)) for v in canvas["offset_px"])
    x0, y0 = origins[0]
    truth = scene[y0 - oy : y0 - oy + canvas["height"], x0 - ox : x0 - ox + canvas["width"]]
    temp, views = layers["temperature"], layers["views"]
    assert views.dtype == np.uint16 and temp.dtype == np.float32
    two = views >= 2
    err = np.abs(temp - truth)[two]
    assert np.median(err) < 0.05 and np.percentile(err, 99) < 0.3
    # the views count matches the known footprints (a pixel of slack at the map edges: the
    # registration is off by a fraction of a pixel)
    inner, outer = (_truth_views(origins, views.shape, canvas["offset_px"], g) for g in (-1, 1))
    assert np.all((inner <= views) & (views <= outer))
    assert np.all(views[inner == outer] == inner[inner == outer])
    assert np.isnan(temp[views == 0]).all() and np.isfinite(temp[views > 0]).all()
    # spread ~ the noise (bilinear resampling of sub-pixel shifts smooths it a little)
    spread = np.nanmedian(layers["spread"][views >= 4])
    assert 0.6 * NOISE_C < spread < 1.3 * NOISE_C
    assert np.isnan(layers["spread"][views < 2]).all()
    mosaic_dir = tmp_path / "mosaic"
    assert (mosaic_dir / "mosaic.png").stat().st_size > 1000
    saved = json.loads((mosaic_dir / "mosaic.json").read_text())
    assert saved["canvas"] == canvas and set(saved["seconds"]) == {
        "registration", "mosaic", "writing", "total"}
    assert sorted(p.name for p in mosaic_dir.iterdir()) == [
        "mosaic.json", "mosaic.png", "sigma.tiff", "spread.tiff", "temperature.tiff", "views.tiff"]


def test_a_map_offset_by_five_degrees_is_rejected(scene, tmp_path):
    origins = _flight_out(tmp_path, scene, 12, bad=5)
    summary = build_mosaic(tmp_path)
    layers = _layers(tmp_path)
    used = {m["frame"]: m for m in summary["maps_used"]}
    bad_frame = 3 + 7 * 5
    assert used[bad_frame]["views_rejected_fraction"] > 0.95  # registered, then outvoted
    others = [m["views_rejected_fraction"] for f, m in used.items() if f != bad_frame]
    assert max(others) < 0.02
    canvas = summary["canvas"]
    ox, oy = (int(round(v)) for v in canvas["offset_px"])
    x0, y0 = origins[0]
    truth = scene[y0 - oy : y0 - oy + canvas["height"], x0 - ox : x0 - ox + canvas["width"]]
    three = layers["views"] >= 3  # where the bad map meets two good ones it loses
    assert np.percentile(np.abs(layers["temperature"] - truth)[three], 99) < 0.3


def test_sigma_layer(scene, tmp_path):
    _flight_out(tmp_path, scene, 8)
    build_mosaic(tmp_path)
    layers = _layers(tmp_path)
    sigma, views = layers["sigma"], layers["views"]
    inside = views > 0
    assert np.isnan(sigma[~inside]).all()
    # fully correlated views: the RMS of their σ, never below the smallest view's σ
    assert np.nanmin(sigma) >= SIGMA_C - 1e-5
    assert np.nanmax(sigma) <= SIGMA_C + 0.01 * 7 + 1e-5
    one = views == 1
    assert np.all((sigma[one] >= SIGMA_C - 1e-5) & (sigma[one] <= SIGMA_C + 0.07 + 1e-5))


def test_no_sigma_maps_no_sigma_layer(scene, tmp_path):
    _flight_out(tmp_path, scene, 4, sigma=False)
    summary = build_mosaic(tmp_path)
    assert summary["sigma"] == {"written": False, "reason": "no σ maps"}
    assert not (tmp_path / "mosaic" / "sigma.tiff").exists()


def test_a_map_that_does_not_register_is_left_out(scene, tmp_path):
    _flight_out(tmp_path, scene, 6)
    noise = np.random.default_rng(5).normal(25.0, 3.0, MAP)  # a map of nothing in the scene
    write_temperature_tiff(tmp_path / "temps" / "frame_000024.tiff", noise)  # the 4th map
    with (tmp_path / "log.jsonl").open("a") as log:  # a failed pivot: logged, no map
        log.write(json.dumps({"frame": 45, "error": "frame 44 is saturated"}) + "\n")
    (tmp_path / "temps" / "frame_000031.tiff").write_bytes(b"II*\x00 cut short")
    summary = build_mosaic(tmp_path)
    out = {e["frame"]: e["reason"] for e in summary["maps_left_out"]}
    assert set(out) == {24, 31, 45}
    assert "registration failed" in out[24] and "saturated" in out[45]
    assert out[31].startswith("unreadable")
    used = [m["frame"] for m in summary["maps_used"]]
    assert used == [3, 10, 17, 38]
    assert summary["maps_used"][3]["registered_to"] == 17  # bridged over the bad maps


def test_a_bad_first_map_is_left_out(scene, tmp_path):
    _flight_out(tmp_path, scene, 5)
    noise = np.random.default_rng(6).normal(25.0, 3.0, MAP)
    write_temperature_tiff(tmp_path / "temps" / "frame_000003.tiff", noise)
    summary = build_mosaic(tmp_path)
    assert [m["frame"] for m in summary["maps_used"]] == [10, 17, 24, 31]
    assert summary["canvas"]["reference_frame"] == 10
    assert [e["frame"] for e in summary["maps_left_out"]] == [3]
    # the reason the map that followed it gave (it said 'no later map registers to it')
    reason = summary["maps_left_out"][0]["reason"]
    assert reason.startswith("map 10 does not register to it (registration failed"), reason


def test_rerun_replaces_the_mosaic(scene, tmp_path):
    _flight_out(tmp_path, scene, 4)
    build_mosaic(tmp_path)
    (tmp_path / ".mosaic.k1ll3d_x").mkdir()  # as a killed run leaves it
    (tmp_path / ".mosaic.k1ll3d_x" / "temperature.tiff").write_bytes(b"half")
    build_mosaic(tmp_path, clip_sigma=2.0)
    saved = json.loads((tmp_path / "mosaic" / "mosaic.json").read_text())
    assert saved["options"]["clip_sigma"] == 2.0
    import tifffile

    for name, unit in (("temperature", "degC"), ("views", "count"), ("spread", "degC")):
        with tifffile.TiffFile(tmp_path / "mosaic" / f"{name}.tiff") as tif:  # each says what
            about = json.loads(tif.pages[0].description)  # it holds, in which unit
        assert about["unit"] == unit and about["quantity"]
    has_sigma = (tmp_path / "mosaic" / "sigma.tiff").exists()
    with tifffile.TiffFile(tmp_path / "mosaic" / "temperature.tiff") as tif:
        assert json.loads(tif.pages[0].description)["sigma"] == (
            "sigma.tiff" if has_sigma else "none")
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_bad_input(scene, tmp_path):
    with pytest.raises(InvalidInputError, match="not the output of thermocal flight"):
        build_mosaic(tmp_path / "nothing")
    out = tmp_path / "empty"
    (out / "temps").mkdir(parents=True)
    (out / "log.jsonl").write_text(json.dumps({"frame": 3, "error": "boom"}) + "\n")
    with pytest.raises(InvalidInputError, match="no temperature map"):
        build_mosaic(out)
    unrelated = tmp_path / "unrelated"
    _flight_out(unrelated, scene, 1)
    rng = np.random.default_rng(9)
    for k in (1, 2):
        write_temperature_tiff(unrelated / "temps" / f"frame_{3 + 7 * k:06d}.tiff",
                               rng.normal(25.0, 3.0, MAP))
    with (unrelated / "log.jsonl").open("a") as log:
        log.write("".join(json.dumps({"frame": 3 + 7 * k}) + "\n" for k in (1, 2)))
    with pytest.raises(InvalidInputError, match="no map registers"):
        build_mosaic(unrelated)
    with pytest.raises(InvalidInputError, match="clip_sigma"):
        build_mosaic(unrelated, clip_sigma=0)
    for folder in (out, unrelated):
        assert not (folder / "mosaic").exists()
        assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []


def test_small_tiles_give_the_same_mosaic(scene, tmp_path, monkeypatch):
    import thermocal.pipeline.mosaic as mosaic

    _flight_out(tmp_path, scene, 6)
    build_mosaic(tmp_path)
    big = _layers(tmp_path)
    monkeypatch.setattr(mosaic, "_TILE_PX", 40)  # tiles across the maps' edges
    monkeypatch.setattr(mosaic, "_MIN_TILE_PX", 4)
    build_mosaic(tmp_path, memory_mb=16.0)
    monkeypatch.setattr(mosaic, "_BYTES_PER_VIEW_PX", 2**20)  # and split in four, again
    build_mosaic(tmp_path, memory_mb=16.0)
    small = _layers(tmp_path)
    for name in big:
        np.testing.assert_allclose(big[name], small[name], atol=1e-4, rtol=0)  # cv2 rounding


def test_command(scene, tmp_path):
    _flight_out(tmp_path, scene, 3)
    result = CliRunner().invoke(mosaic_command, [str(tmp_path)])
    assert result.exit_code == 0, result.output
    assert "mosaic of 3 maps (0 left out)" in result.output
    # the folder readable as a plain mkdir's (it was tempfile's private 0700)
    (tmp_path / "plain").mkdir()
    assert (tmp_path / "mosaic").stat().st_mode & 0o777 == (tmp_path / "plain").stat().st_mode \
        & 0o777


def test_a_simulated_uav_pass(tmp_path):
    """Maps rendered along a simulated UAV pass (thermocal.simulate.flight: 3.8 px per frame,
    attitude jitter) at the pivots of stride 7: the chained transforms follow the true ones."""
    import cv2

    from thermocal.camera import make_camera
    from thermocal.registration.warp import frame_corners, map_points, render_views
    from thermocal.simulate.flight import plan_flight

    camera = make_camera("tau2", unit=3, size=(160, 128))
    plan = plan_flight(_scene((200, 300), seed=4), camera, n_frames=60, motion="uav", seed=1)
    pivots = list(range(3, 57, 7))
    maps = render_views(plan.big_map, plan.to_map[pivots], (160, 128))
    rng = np.random.default_rng(2)
    (tmp_path / "temps").mkdir()
    for pivot, temp in zip(pivots, maps, strict=True):
        write_temperature_tiff(tmp_path / "temps" / f"frame_{pivot:06d}.tiff",
                               temp + rng.normal(0.0, NOISE_C, temp.shape))
    (tmp_path / "log.jsonl").write_text("".join(json.dumps({"frame": p}) + "\n" for p in pivots))
    summary = build_mosaic(tmp_path)
    assert [m["frame"] for m in summary["maps_used"]] == pivots
    to_canvas = np.array([m["to_canvas"] for m in summary["maps_used"]])
    # canvas → first map → scene map: the true place of every map's corners
    canvas_to_map = plan.to_map[pivots[0]] @ np.linalg.inv(to_canvas[0])
    corners = frame_corners((160, 128))
    for h_est, h_true in zip(to_canvas, plan.to_map[pivots], strict=True):
        est = map_points(canvas_to_map @ h_est, corners)[0]
        assert np.abs(est - map_points(h_true, corners)[0]).max() < 0.5  # pixels
    temp = tifffile.imread(tmp_path / "mosaic" / "temperature.tiff")
    views = tifffile.imread(tmp_path / "mosaic" / "views.tiff")
    seen = cv2.warpPerspective(plan.big_map, canvas_to_map, (temp.shape[1], temp.shape[0]),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    err = np.abs(temp - seen)[views >= 2]
    assert np.median(err) < 0.05 and np.percentile(err, 95) < 0.15


def test_a_processed_flight(tmp_path):
    """End to end: a simulated chamber → a calibration; a simulated UAV pass → thermocal flight
    (``--method calibration``, stride 3) → the mosaic, against the scene the pass flew over."""
    import cv2

    from thermocal.calibration.report import fit_with_report
    from thermocal.camera import make_camera
    from thermocal.pipeline.flight import FlightOptions, process_flight
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
    from thermocal.simulate.flight import plan_flight, write_simulated_flight

    camera = make_camera("tau2", unit=9, size=(128, 96))
    plan = ChamberPlan(setpoints_c=(10.0, 20.0, 30.0, 40.0, 50.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.2,
                       interval_s=20.0)
    write_simulated_chamber(tmp_path / "chamber.h5", camera, plan, seed=1)
    fit_with_report(tmp_path / "chamber.h5", "polynomial",
                    frames="settled")[0].save(tmp_path / "cal.h5")
    flight = plan_flight(_scene((160, 240), seed=3), camera, n_frames=40, motion="uav",
                         fpa_c=28.0, seed=2)
    write_simulated_flight(tmp_path / "flight", flight, camera)
    out = tmp_path / "out"
    process_flight(tmp_path / "flight" / "frames.tiff", out,
                   FlightOptions(method="calibration", calibration=str(tmp_path / "cal.h5"),
                                 stride=3, preview_every=0))
    summary = build_mosaic(out)
    pivots = [m["frame"] for m in summary["maps_used"]]
    assert len(pivots) >= 10 and summary["maps_left_out"] == []
    temp = tifffile.imread(out / "mosaic" / "temperature.tiff")
    views = tifffile.imread(out / "mosaic" / "views.tiff")
    canvas_to_map = flight.to_map[pivots[0]] @ np.linalg.inv(summary["maps_used"][0]["to_canvas"])
    seen = cv2.warpPerspective(flight.big_map, canvas_to_map, (temp.shape[1], temp.shape[0]),
                               flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)
    err = np.abs(temp - seen)[views >= 2]
    assert np.median(err) < 0.1 and np.percentile(err, 95) < 0.3  # measured 0.05, 0.18
    assert summary["views"]["rejected_fraction"] < 0.01
    assert summary["sigma"]["written"] and (out / "mosaic" / "sigma.tiff").is_file()
    # a map whose σ map the flight wrote and which is now missing is left out, not used
    # without σ (the whole mosaic was written without one, said in mosaic.json alone)
    lost = pivots[len(pivots) // 2]
    (out / "temps" / f"frame_{lost:06d}_sigma.tiff").unlink()
    again = build_mosaic(out)
    assert [m["frame"] for m in again["maps_left_out"]] == [lost]
    assert "σ" in again["maps_left_out"][0]["reason"] and again["sigma"]["written"]
