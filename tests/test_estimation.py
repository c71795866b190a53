"""The estimation pipeline, its registry and protocol, and the package's import graph."""

from __future__ import annotations

import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from thermocal.camera.presets import make_camera
from thermocal.errors import InvalidInputError, OutsideDomainError, ResolutionMismatchError
from thermocal.estimation import ESTIMATORS, Estimator, PreparedBurst, estimate, make_estimator
from thermocal.estimation.calibrated import OzMean, PivotCalibration
from thermocal.registration.warp import warp_to_pivot
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def flight():
    """Five frames of a walk of a 64×48 unit with three hot pixels."""
    cam = make_camera("tau2", unit=101, size=(64, 48))
    defects = np.zeros(cam.shape, bool)
    counts = np.zeros(cam.shape, np.uint16)
    for r, c in ((5, 7), (20, 30), (40, 60)):
        defects[r, c], counts[r, c] = True, 16383
    cam = replace(cam, defects=defects, defect_counts=counts)
    scene = procedural_scene((200, 200), rng=np.random.default_rng(2), kind="urban")
    return simulate_flight(scene, cam, n_frames=5, motion="walk", fpa_c=30.0, seed=4)


class Recorder:
    """A test estimator: a per-pixel map it records, and the burst it was given."""

    name = "recorder"
    n_frames = None
    needs_fpa = True
    accepts_registered = False
    remedy = "record it again"
    fpa_paces: dict = {}

    def __init__(self, *, per_frame: bool = False, outside: tuple[str, ...] = ()) -> None:
        self.reasons = outside
        self.per_frame = per_frame
        self.seen: list[tuple] = []
        self.burst: PreparedBurst | None = None

    def check(self, frames, *, registered, homographies):
        self.seen.append(("check", frames.shape))

    def calibrate(self, frames, fpa_c, time_s, *, pace=None):
        self.seen.append(("calibrate", frames.copy(), fpa_c))
        return frames.astype(np.float32) * 0.5 + np.arange(frames.shape[2], dtype=np.float32)

    def outside(self, calibrated, fpa_c, *, pace=None, burst=None):
        self.seen.append(("outside", calibrated.shape, fpa_c, burst))
        return self.reasons

    def estimate(self, burst):
        self.burst = burst
        return burst.warped[burst.pivot]

    def uncertainty(self, burst, temperature_c, *, outside):
        return np.full(temperature_c.shape, 9.0 if outside else 1.0, np.float32)


def test_pipeline_stages_in_order_on_the_filled_frames(flight):
    rec = Recorder()
    assert isinstance(rec, Estimator)
    before = flight.frames.copy()
    est = estimate(flight.frames, rec, fpa_c=flight.fpa_c, homographies=flight.homographies)
    assert np.array_equal(flight.frames, before)  # the input is not changed
    assert [s[0] for s in rec.seen] == ["check", "calibrate", "outside"]
    filled = rec.seen[1][1]
    assert not np.array_equal(filled, flight.frames)  # the defects were replaced before …
    assert rec.seen[1][2] == pytest.approx(float(np.mean(flight.fpa_c)))  # … one FPA value
    want, valid = warp_to_pivot(rec.calibrate(filled, None, None), flight.homographies)
    b = rec.burst
    assert np.array_equal(b.warped, want) and np.array_equal(b.valid, valid)  # … warping
    assert np.array_equal(b.frames, filled) and b.pivot == 2
    assert rec.seen[2][3] is b  # the domain is checked on the registered burst
    assert np.array_equal(est.temperature_c, want[2])
    assert np.array_equal(est.coverage, valid.sum(axis=0))
    with pytest.raises(InvalidInputError, match="as recorded"):
        estimate(flight.frames, Recorder(), fpa_c=30.0, registered=True)
    with pytest.raises(InvalidInputError, match="no FPA temperature"):
        estimate(flight.frames, Recorder(), homographies=flight.homographies)
    with pytest.raises(InvalidInputError, match="pivot 9"):
        estimate(flight.frames, Recorder(), fpa_c=30.0, pivot=9)


def test_per_frame_estimator_sees_no_registration(flight):
    rec = Recorder(per_frame=True)
    est = estimate(flight.frames, rec, fpa_c=30.0, pivot=1)
    assert [s[0] for s in rec.seen] == ["check", "calibrate", "outside"]
    seen, clipped = rec.seen[1][1], flight.frames[1] >= 16383
    assert clipped.sum() == 3  # the unit's three hot pixels, at the top count
    # raw, not registered, its pivot's clipped counts filled from their neighbours (a
    # saturated pixel says nothing of the scene), the other frames as they were
    assert np.array_equal(np.delete(seen, 1, axis=0), np.delete(flight.frames, 1, axis=0))
    assert np.array_equal(seen[1][~clipped], flight.frames[1][~clipped])
    assert np.all(seen[1][clipped] < 16383) and flight.frames[1][clipped].min() == 16383
    # … its domain checked on the burst as it lies (its pivot: is it the calibration's
    # camera?), not registered
    assert rec.seen[2][3] is rec.burst and np.array_equal(rec.burst.frames, seen)
    assert np.array_equal(rec.burst.homographies,
                          np.repeat(np.eye(3)[None], len(flight.frames), axis=0))
    assert rec.seen[2][1] == (1, *flight.frames.shape[1:])  # … on the pivot alone
    # … at its own FPA temperature, not the recording's mean (a warming recording's last frame
    # at 47 °C was checked at its 36 °C mean)
    ramp = np.linspace(25.0, 47.0, flight.frames.shape[0])
    warm = Recorder(per_frame=True)
    estimate(flight.frames, warm, fpa_c=ramp, pivot=len(ramp) - 1)
    assert warm.seen[2][2] == pytest.approx(47.0) and warm.burst.fpa_c == pytest.approx(47.0)
    assert np.array_equal(est.temperature_c, rec.calibrate(seen, None, None)[1])
    block = flight.frames.copy()  # a saturated object, not a defect: left for the domain
    block[1, 30:34, 10:14] = 16383  # check, which sees the top count's temperature
    seen_block = Recorder(per_frame=True)
    estimate(block, seen_block, fpa_c=30.0, pivot=1)
    assert np.all(seen_block.seen[1][1][1, 30:34, 10:14] == 16383)
    kept = Recorder(per_frame=True)  # without filling: the raw burst
    estimate(flight.frames, kept, fpa_c=30.0, pivot=1, fill_defects=False)
    assert np.array_equal(kept.seen[1][1], flight.frames)
    assert np.all(est.coverage == 1) and np.array_equal(est.homographies[1], np.eye(3))


def test_estimate_takes_the_pivots_pace_from_its_whole_recording():
    """``thermocal estimate`` judges the pivot's pace as a flight does, from the recording
    (it judged every recording steady, "its pace not known from so short a recording")."""
    from types import SimpleNamespace

    from thermocal.estimation.commands import _pivot_pace

    t = np.arange(0.0, 1200.0, 10.0)
    rec = SimpleNamespace(fpa_c=20.0 + np.maximum(t - 400.0, 0.0) / 60.0, time_s=t)  # still,
    paced = SimpleNamespace(fpa_paces={"lag_s": 480.0})  # then 1 °C/min from 400 s on
    got = _pivot_pace(rec, paced, slice(0, t.size), None)
    assert got["fpa_rate_c_per_min"] == pytest.approx(1.0, abs=0.02)
    assert 0.2 < got["fpa_lagged_rate_c_per_min"] < 0.5  # the lag catching up, 200 s in
    assert got["time_since_start_s"] == t[t.size // 2] and got["fpa_still_s"] is None
    late = _pivot_pace(rec, paced, slice(110, 117), 3)
    assert late["time_since_start_s"] == t[113]
    plain = _pivot_pace(rec, SimpleNamespace(fpa_paces={}), slice(0, t.size), 80)
    assert plain["fpa_lagged_rate_c_per_min"] is None and plain["fpa_rate_c_per_min"] > 0.9
    assert _pivot_pace(rec, paced, slice(0, 7), 9)["fpa_rate_c_per_min"] is None  # bad pivot
    still = SimpleNamespace(fpa_c=None, time_s=None)
    assert all(v is None for v in _pivot_pace(still, paced, slice(0, 1), 0).values())
    # one FPA value for the whole recording (--fpa-c): no history measured, none taken (a
    # lin-lag burst took a steady history it never had: σ 8× too small)
    given = SimpleNamespace(fpa_c=np.full(t.size, 30.0), time_s=t)
    lagged = SimpleNamespace(fpa_paces={"lag_s": 480.0}, rate_lags_s=(60.0, 480.0))
    got = _pivot_pace(given, lagged, slice(0, t.size), None)
    assert all(got[k] is None for k in got if k != "time_since_start_s")
    moving = _pivot_pace(rec, lagged, slice(0, t.size), None)["fpa_lag_rates_c_per_min"]
    assert moving.shape == (2,) and moving[0] > moving[1] > 0  # the shorter lag nearer 1


def test_calibration_estimators(flight, small_camera):
    from thermocal.calibration.two_point import fit_two_point
    from thermocal.camera.model import render

    cam = make_camera("tau2", unit=101, size=(64, 48))
    rng = np.random.default_rng(0)
    lo = render(cam, np.full(8, 10.0), 30.0, housing_c=29.0, rng=rng)
    hi = render(cam, np.full(8, 50.0), 30.0, housing_c=29.0, rng=rng)
    cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=30.0)
    for est in (OzMean(cal), PivotCalibration(cal)):
        assert isinstance(est, Estimator)
    pivot_only = estimate(flight.frames, PivotCalibration(cal), fpa_c=flight.fpa_c)
    applied = cal.apply(flight.frames, fpa_c=flight.fpa_c)[2]
    clipped = flight.frames[2] >= 16383  # the unit's hot pixels: filled, the rest as applied
    assert np.array_equal(pivot_only.temperature_c[~clipped], applied[~clipped])
    truth = flight.truth_c[flight.pivot]
    assert np.abs(applied - truth)[clipped].min() > 20.0  # a saturated count read as is
    assert np.abs(pivot_only.temperature_c - truth)[clipped].max() < 5.0
    mean = estimate(flight.frames, OzMean(cal), homographies=flight.homographies)
    inner = mean.coverage == 5
    assert np.median(np.abs(mean.temperature_c - truth)[inner]) < 1.0
    small = make_camera("tau2", unit=0, size=(32, 24))
    lo2 = render(small, np.full(4, 10.0), 30.0, housing_c=29.0, rng=rng)
    hi2 = render(small, np.full(4, 50.0), 30.0, housing_c=29.0, rng=rng)
    with pytest.raises(ResolutionMismatchError, match="calibration is 32x24"):
        estimate(flight.frames, OzMean(fit_two_point(lo2, hi2, 10.0, 50.0, fpa_ref_c=30.0)))


def test_registry_names_and_refusals():
    assert list(ESTIMATORS)[0] == "kpn"
    assert {"kpn", "kpn-no-offset", "e2e", "mean", "calibration"} <= set(ESTIMATORS)
    with pytest.raises(InvalidInputError, match="unknown method 'nope'"):
        make_estimator("nope")
    with pytest.raises(InvalidInputError, match="needs a per-pixel calibration"):
        make_estimator("mean")


def test_cli_choices_come_from_the_registry():
    from click.testing import CliRunner

    from thermocal.cli import cli

    for command in ("estimate", "flight"):
        text = CliRunner().invoke(cli, [command, "--help"], terminal_width=200).output
        for name in ESTIMATORS:
            assert name in text, (command, name)


def test_readme_names_every_registered_method():
    from thermocal.calibration import CALIBRATION_METHODS
    from thermocal.nuc import NUC_METHODS

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    names = [*ESTIMATORS, *CALIBRATION_METHODS, *NUC_METHODS]
    missing = [n for n in names if not re.search(rf"`{re.escape(n)}`", readme)]
    assert not missing, f"README.md does not name these registered methods: {missing}"


def test_no_import_cycles():
    """No cycle in the import graph of thermocal, counting imports inside functions."""
    grimp = pytest.importorskip("grimp")
    nx = pytest.importorskip("networkx")
    graph = grimp.build_graph("thermocal", exclude_type_checking_imports=True)
    edges = nx.DiGraph()
    for module in graph.modules:
        for imported in graph.find_modules_directly_imported_by(module):
            edges.add_edge(module, imported)
    cycles = [sorted(c) for c in nx.strongly_connected_components(edges) if len(c) > 1]
    assert not cycles, f"import cycles: {cycles}"


def test_burst_and_pipeline_import_no_network_code():
    grimp = pytest.importorskip("grimp")
    graph = grimp.build_graph("thermocal", exclude_type_checking_imports=True)
    network = {"thermocal.nn.model", "thermocal.nn.infer", "thermocal.nn.train",
               "thermocal.nn.store"}
    for module in ("thermocal.burst", "thermocal.estimation.pipeline",
                   "thermocal.estimation.base", "thermocal.estimation.calibrated"):
        assert not graph.find_upstream_modules(module) & network, module


def test_thermocal_estimate_with_a_calibration(tmp_path, flight, capsys):
    """``thermocal estimate --method mean|calibration`` end to end: a recording in, the pivot's
    map out (that of the pipeline), and the one-line refusals."""
    import tifffile

    from thermocal.calibration.two_point import fit_two_point
    from thermocal.camera.model import render
    from thermocal.cli import main
    from thermocal.io.recording import Recording, write_recording

    cam = make_camera("tau2", unit=101, size=(64, 48))
    rng = np.random.default_rng(0)
    lo = render(cam, np.full(8, 10.0), 30.0, housing_c=29.0, rng=rng)
    hi = render(cam, np.full(8, 50.0), 30.0, housing_c=29.0, rng=rng)
    cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=30.0)
    cal.save(tmp_path / "cal.h5")
    write_recording(tmp_path / "burst.tiff", Recording(flight.frames, fpa_c=flight.fpa_c))
    for method, est in (("calibration", PivotCalibration(cal)), ("mean", OzMean(cal))):
        out = tmp_path / f"{method}.tiff"
        argv = ["estimate", str(tmp_path / "burst.tiff"), "--method", method, "--calibration",
                str(tmp_path / "cal.h5"), "--registered", "--out", str(out)]
        # a file without a cross-validation report cannot be checked: refused, unless --force
        with pytest.raises(SystemExit) as exc:
            main(argv)
        err = capsys.readouterr().err
        assert exc.value.code == 2 and "no cross-validation report" in err and "--force" in err
        assert not out.exists()
        main([*argv, "--force"])
        err = capsys.readouterr().err
        assert "warning" in err and "no cross-validation report" in err
        want = estimate(flight.frames, est, fpa_c=flight.fpa_c, registered=True)
        assert np.array_equal(tifffile.imread(out), want.temperature_c)
    with pytest.raises(SystemExit) as exc:
        main(["estimate", str(tmp_path / "burst.tiff"), "--method", "mean", "--out",
              str(tmp_path / "x.tiff")])
    assert exc.value.code == 2
    assert "needs a per-pixel calibration" in capsys.readouterr().err
    assert not (tmp_path / "x.tiff").exists()


def test_registry_and_estimators_agree_on_per_frame(flight):
    from thermocal.calibration.two_point import fit_two_point
    from thermocal.camera.model import render

    cam = make_camera("tau2", unit=101, size=(64, 48))
    rng = np.random.default_rng(0)
    lo = render(cam, np.full(4, 10.0), 30.0, housing_c=29.0, rng=rng)
    hi = render(cam, np.full(4, 50.0), 30.0, housing_c=29.0, rng=rng)
    cal = fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=30.0)
    for name, info in ESTIMATORS.items():
        if info.needs == "calibration":
            assert make_estimator(name, calibration=cal).per_frame == info.per_frame, name
    pytest.importorskip("torch")
    assert make_estimator("kpn").per_frame == ESTIMATORS["kpn"].per_frame


def test_outside_the_domain_is_refused_unless_forced(flight):
    """Stage 4's domain check: refused with every reason and the remedy in one line; with
    ``force`` estimated all the same, the reasons kept in the Estimate."""
    for per_frame in (False, True):
        rec = Recorder(per_frame=per_frame, outside=("too hot", "too shiny"))
        with pytest.raises(OutsideDomainError, match="^too hot; too shiny; record it again$"):
            estimate(flight.frames, rec, fpa_c=flight.fpa_c, homographies=flight.homographies)
        assert rec.burst is None  # refused before the estimate
        est = estimate(flight.frames, Recorder(per_frame=per_frame, outside=("too hot",)),
                       fpa_c=flight.fpa_c, homographies=flight.homographies, force=True)
        assert est.outside == ("too hot",) and np.all(est.sigma_c == 9.0)
    inside = estimate(flight.frames, Recorder(), fpa_c=flight.fpa_c,
                      homographies=flight.homographies)
    assert inside.outside == () and np.all(inside.sigma_c == 1.0)


def test_every_estimator_that_may_lack_sigma_says_what_to_do():
    from thermocal.estimation.commands import NO_SIGMA_REMEDY

    for name, info in ESTIMATORS.items():  # "recording": the file's constants carry their σ
        assert info.needs == "recording" or info.needs in NO_SIGMA_REMEDY, name


def test_calibrations_get_the_frames_times(flight):
    """Both calibration estimators hand the calibration the frames' times (a rate term needs
    them: the mean's frames were calibrated without, and a lin calibration refused them)."""
    seen = []

    class Spy:
        shape = flight.frames.shape[1:]

        def apply(self, frames, *, fpa_c=None, time_s=None):
            seen.append(time_s)
            return np.zeros(np.shape(frames), dtype=np.float32)

    t = np.arange(len(flight.frames)) / 30.0
    for cls in (OzMean, PivotCalibration):
        est = cls.__new__(cls)
        est.calibration, est.sigma_model = Spy(), None
        est.calibrate(flight.frames, 30.0, t)
        assert seen.pop() is t, cls.__name__


def test_selfcal_gives_its_start_calibration_the_times_and_rate(flight):
    """selfcal from a lin calibration: the frames' times and, from the whole recording, their
    FPA rate (it gave neither: lin refused a batch whose FPA moved, or dropped its rate term)."""
    from thermocal.estimation.selfcal import SelfCalibration

    seen = {}

    class Spy:
        shape = flight.frames.shape[1:]
        takes_fpa_rate = True
        bad = np.zeros(shape, dtype=bool)

        def apply(self, frames, *, fpa_c=None, time_s=None, fpa_rate_c_per_min=None):
            seen.update(time_s=time_s, rate=fpa_rate_c_per_min)
            return np.full(np.shape(frames), 20.0, dtype=np.float32)

    t = np.arange(len(flight.frames)) / 30.0
    est = SelfCalibration(Spy(), fpa_rates=(t, np.full(t.size, 0.7)))
    est.start_temperature(flight.frames, 30.0, t)
    assert seen["time_s"] is t
    np.testing.assert_allclose(seen["rate"], 0.7)
