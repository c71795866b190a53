"""thermocal report: the flight's one-page HTML report, self-contained and escaped; bad input."""

from __future__ import annotations

import base64
import io
import json
import re

import numpy as np
import pytest
import tifffile
from cli_run import run
from click.testing import CliRunner
from PIL import Image

from thermocal.errors import InvalidInputError
from thermocal.io.recording import write_sigma_tiff, write_temperature_tiff
from thermocal.pipeline.commands import report as report_command
from thermocal.pipeline.report import REPORT_NAME, write_report

EVIL = "<script>alert(1)</script>"


def _attributes(page: str) -> list[str]:
    """Every src/href value and every tag that could load something."""
    return re.findall(r'(?:src|href)\s*=\s*"([^"]*)"', page)


def _self_contained(page: str) -> None:
    assert "<link" not in page and "<script" not in page and "@import" not in page
    assert "url(" not in page
    sources = _attributes(page)
    assert sources and all(s.startswith("data:image/png;base64,") for s in sources)


def _fake_flight(out, *, n=5, method="kpn", sigma=True, failed=(), warned=(),
                 recording="/data/flight.tiff", **summary_keys):
    """A flight output written directly: ``n`` pivots (frames 3, 10, …), the ``failed`` ones
    with an error, the ``warned`` ones with a warning."""
    (out / "temps").mkdir(parents=True)
    (out / "previews").mkdir()
    rng = np.random.default_rng(0)
    lines = []
    for k in range(n):
        frame = 3 + 7 * k
        entry = {"frame": frame, "time_s": frame / 10, "fpa_c": 30.0 + 0.01 * k, "warnings": []}
        if frame in failed:
            entry["error"] = f"frame {frame} is saturated ({50 + k} % of its pixels); <b>x</b>"
        else:
            temp = (20 + 10 * rng.random((12, 16))).astype(np.float32)
            write_temperature_tiff(out / "temps" / f"frame_{frame:06d}.tiff", temp)
            entry["mean_c"] = float(temp.mean())
            if sigma:
                write_sigma_tiff(out / "temps" / f"frame_{frame:06d}_sigma.tiff",
                                 np.full((12, 16), 0.8, np.float32))
                entry["sigma_median_c"], entry["sigma_p95_c"] = 0.8, 1.2
            if frame in warned:
                entry["warnings"] = [f"FPA changing fast ({frame} °C/min) {EVIL}"]
            preview = out / "previews" / f"frame_{frame:06d}.png"
            Image.new("RGB", (40, 30), (200, 80, 20)).save(preview)
        lines.append(json.dumps(entry))
    (out / "log.jsonl").write_text("\n".join(lines) + "\n")
    summary = {"recording": recording, "options": {"method": method, "calibration": None,
                                                   "model": None, "frames": 7, "stride": 7,
                                                   "force": False},
               "groups": n, "processed": n - len(failed), "skipped_already_done": 0,
               "failed": len(failed),
               "sigma_c": {"median_of_medians": 0.8, "max_p95": 1.2, "maps": n - len(failed)}
               if sigma else None, "wall_time_s": 1.5} | summary_keys
    (out / "summary.json").write_text(json.dumps(summary))
    return out


def test_real_flight_report_via_the_command(tmp_path, capsys):
    """thermocal simulate flight + flight (kpn, frames too small for the network's family
    check, forced: every group estimated with a warning), then the report command."""
    rec, out = tmp_path / "rec", tmp_path / "out"
    assert run(["simulate", "flight", rec, "--frames", 21, "--size", "64x48", "--motion",
                "uav"], capsys)[0] == 0
    assert run(["flight", rec / "frames.tiff", "--out", out, "--method", "kpn", "--force"],
               capsys)[0] == 0
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    summary = json.loads((out / "summary.json").read_text())
    assert (out / REPORT_NAME).is_file()  # the flight writes its report
    assert json.loads((out / "summary.json").read_text())["command"].startswith(
        "thermocal flight")
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != REPORT_NAME}

    result = CliRunner().invoke(report_command, [str(out)])
    assert result.exit_code == 0, result.output
    assert str(out / REPORT_NAME) in result.output
    after = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != REPORT_NAME}
    assert after == before  # the flight's files are only read
    page = (out / REPORT_NAME).read_text(encoding="utf-8")
    _self_contained(page)
    assert "<b>kpn</b>" in page and "kpn_n7.sigma.json" in page
    assert f"{summary['sigma_c']['median_of_medians']:.2f} °C" in page
    assert f"{summary['sigma_c']['max_p95']:.2f} °C" in page
    warned = [e for e in log if e.get("warnings")]
    assert summary["failed"] == 0 and len(warned) == summary["processed"] >= 1
    assert "No group failed" in page and "--force: groups outside the method" in page
    for e in warned:
        assert str(e["frame"]) in page
    assert "too small to check" in page
    assert "68 %" in page and "1σ" in page


def test_escapes_names_and_messages(tmp_path):
    out = _fake_flight(tmp_path / "out", failed=(10,), warned=(17,),
                       recording=f"/data/{EVIL}.tiff", command=f"thermocal flight {EVIL}")
    page = write_report(out).read_text(encoding="utf-8")
    _self_contained(page)
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert "&lt;b&gt;x&lt;/b&gt;" in page and "<b>x</b>" not in page
    assert "thermocal flight &lt;script&gt;" in page  # the command, shown


def test_failures_and_warnings_grouped_by_reason(tmp_path):
    out = _fake_flight(tmp_path / "out", n=8, failed=(10, 24, 38), warned=(3, 17))
    page = write_report(out).read_text(encoding="utf-8")
    # one reason (only the numbers differ), its count and its frames
    assert page.count("is saturated") == 1
    assert re.search(r'<td class="n">3</td><td>frame 10 is saturated.*?</td><td>10, 24, 38</td>',
                     page)
    assert page.count("FPA changing fast") == 1 and "3, 17" in page
    assert "5 of 8 groups gave a map" in page and "3 failed" in page
    assert "2 with warnings" in page


def test_a_sigma_known_not_to_hold_somewhere_says_so(tmp_path):
    """An e2e flight's summary carries its σ's caveat (the flight writes it from the variant's
    registry entry), and the report shows it as a warning beside the stated accuracy."""
    from thermocal.nn.variants import VARIANTS
    from thermocal.pipeline.flight import _sigma_summary

    entries = [{"sigma_median_c": 5.0, "sigma_p95_c": 6.0}]
    assert _sigma_summary(entries, "e2e")["caveat"] == VARIANTS["e2e"].sigma_caveat
    assert "caveat" not in _sigma_summary(entries, "kpn")  # its σ holds where measured
    assert "caveat" not in _sigma_summary(entries, "calibration")
    assert _sigma_summary([{}], "e2e") is None  # no σ, no caveat
    out = _fake_flight(tmp_path / "out", method="e2e")
    summary = json.loads((out / "summary.json").read_text())
    summary["sigma_c"]["caveat"] = VARIANTS["e2e"].sigma_caveat
    (out / "summary.json").write_text(json.dumps(summary))
    page = write_report(out).read_text(encoding="utf-8")
    assert ('<span class="warn">e2e: its σ is fitted on bursts of the scenes it was trained '
            "on") in page
    plain = write_report(_fake_flight(tmp_path / "kpn")).read_text(encoding="utf-8")
    assert "it was trained on" not in plain


def test_without_sigma_says_so_plainly(tmp_path):
    out = _fake_flight(tmp_path / "out", method="calibration", sigma=False)
    page = write_report(out).read_text(encoding="utf-8")
    assert "no uncertainty model" in page
    assert "median σ (°C)" not in page  # no σ panel


def test_mosaic_shown_when_present_and_big_tables_subsampled(tmp_path):
    out = _fake_flight(tmp_path / "out", n=30, resumed=True, skipped_already_done=12)
    (out / "mosaic").mkdir()
    Image.new("RGB", (2400, 600), (10, 120, 200)).save(out / "mosaic" / "mosaic.png")
    sigma = np.full((60, 80), 0.7, np.float32)
    sigma[:10] = np.nan  # outside every view
    tifffile.imwrite(out / "mosaic" / "sigma.tiff", sigma)
    (out / "mosaic" / "mosaic.json").write_text(json.dumps({
        "canvas": {"width": 80, "height": 60, "covered_fraction": 0.83},
        "maps_used": [{"frame": 3}, {"frame": 10}],
        "maps_left_out": [{"frame": 17, "reason": f"correlation 0.12 {EVIL}"},
                          {"frame": 24, "reason": f"correlation 0.31 {EVIL}"}],
        "views": {"max": 4, "median": 2.0, "rejected_fraction": 0.01}}))
    page = write_report(out, max_rows=10).read_text(encoding="utf-8")
    _self_contained(page)
    assert "<h2>Mosaic</h2>" in page and "mosaic/sigma.tiff" in page
    assert "mosaic/mosaic.png" in page  # no temperature.tiff: its preview
    assert "pivot previews" not in page
    assert "canvas 80 × 60 px, 83 % covered" in page and "2 maps used, 2 left out" in page
    assert "left out (2): correlation 0.12 &lt;script&gt;" in page and "(frames 17, 24)" in page
    assert EVIL not in page
    assert "10 of 30 groups shown" in page
    assert "12 groups were already done" in page
    shown = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    widths = [Image.open(io.BytesIO(base64.b64decode(s))).width for s in shown]
    assert max(widths) <= 1100  # the 2400-px mosaic scaled down


def test_a_mosaic_older_than_the_maps_is_said_to_be_out_of_date(tmp_path):
    """A flight resumed (or rerun) after ``thermocal mosaic`` made maps the mosaic never saw:
    the report says so and how to remake it (it showed the old mosaic as current, its 'not in
    log.jsonl' left-outs long logged); a map left out for its own fault is no sign of age."""
    out = _fake_flight(tmp_path / "out")  # frames 3, 10, 17, 24, 31
    (out / "mosaic").mkdir()
    Image.new("RGB", (20, 20)).save(out / "mosaic" / "mosaic.png")

    def mosaic(used, left):
        (out / "mosaic" / "mosaic.json").write_text(json.dumps({
            "maps_used": [{"frame": f} for f in used],
            "maps_left_out": [{"frame": f, "reason": r} for f, r in left]}))
        return write_report(out).read_text(encoding="utf-8")

    page = mosaic([3, 10], [(17, "correlation 0.12"), (24, "not in log.jsonl")])
    assert "This mosaic is out of date: it was made before 2 maps of this folder (frames " \
           "24, 31); run <code>thermocal mosaic" in page
    page = mosaic([3, 10, 24, 31], [(17, "correlation 0.12")])
    assert "out of date" not in page
    # a map the mosaic missed that is still missing: no sign of age (remaking cannot help)
    (out / "temps" / "frame_000031.tiff").unlink()
    page = mosaic([3, 10, 24], [(17, "correlation 0.12"),
                                (31, "no map: frame_000031.tiff is missing")])
    assert "out of date" not in page


def test_mosaic_layers_drawn_from_the_tiffs(tmp_path):
    out = _fake_flight(tmp_path / "out")
    (out / "mosaic").mkdir()
    temp = np.full((30, 200), 25.0, np.float32)
    temp[:, :20] = np.nan
    tifffile.imwrite(out / "mosaic" / "temperature.tiff", temp)
    Image.new("RGB", (20, 20)).save(out / "mosaic" / "mosaic.png")
    (out / "mosaic" / "sigma.tiff").write_bytes(b"II*\0 damaged")
    page = write_report(out).read_text(encoding="utf-8")
    assert "mosaic/temperature.tiff" in page
    assert "mosaic/mosaic.png" not in page and "mosaic/sigma.tiff" not in page


def test_previews_when_no_mosaic_and_missing_maps_flagged(tmp_path):
    out = _fake_flight(tmp_path / "out", n=9)
    (out / "temps" / "frame_000010.tiff").unlink()
    page = write_report(out, previews=3).read_text(encoding="utf-8")
    assert "3 of 9 pivot previews" in page
    assert "map missing or unreadable" in page and "1 logged maps are missing" in page
    # and the verdict says so: the maps it counts are the log's, one no longer on disk
    assert "1 of those maps no longer in temps/" in page
    (out / "temps" / "frame_000010.tiff").write_bytes(b"back")  # there, if unreadable: table
    assert "no longer in temps/" not in write_report(out).read_text(encoding="utf-8")


@pytest.mark.parametrize("damage", ["missing", "not json", "a list", "no options", "a file"])
def test_bad_input_one_line_nothing_written(tmp_path, damage):
    out = _fake_flight(tmp_path / "out")
    summary = out / "summary.json"
    if damage == "missing":
        summary.unlink()
    elif damage == "not json":
        summary.write_text('{"recording": "x", "opt')
    elif damage == "a list":
        summary.write_text("[1, 2]")
    elif damage == "no options":
        summary.write_text(json.dumps({"recording": "x", "groups": 3}))
    target = out if damage != "a file" else summary
    with pytest.raises(InvalidInputError) as info:
        write_report(target)
    assert "\n" not in str(info.value) and ("rerun" in str(info.value)
                                            or "give" in str(info.value))
    assert not (out / REPORT_NAME).exists()
    result = CliRunner().invoke(report_command, [str(target)])
    assert result.exit_code != 0 and isinstance(result.exception, InvalidInputError)
    assert not (out / REPORT_NAME).exists()
    assert not [p for p in out.iterdir() if p.name.startswith(".report")]


def test_bad_options():
    with pytest.raises(InvalidInputError):
        write_report(".", max_rows=0)
