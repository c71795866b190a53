"""The cross-physics benchmark suite (``thermocal.evaluation.suites.physics``): its structure, the
chamber runs it records, and the physics it must show (a calibration of one camera family is
far off on the other)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from thermocal.calibration import CALIBRATION_METHODS, fit_calibration
from thermocal.camera.presets import make_camera
from thermocal.evaluation.suites import SUITES
from thermocal.evaluation.suites import physics as P
from thermocal.simulate.chamber import radiance_temperature_c

SIZE = (32, 24)


@pytest.fixture(scope="module")
def tiny():
    """Part 1 of the suite on 32x24 crops with the quick protocol."""
    return P.bench_calibrations(True, size=SIZE)


def _row(res, method, fit_on, on):
    return next(r for r in res["rows"] if (r["method"], r["fitted_on"], r["evaluated_on"])
                == (method, fit_on, on))


def test_the_suite_is_registered():
    assert "physics" in SUITES and P.FAMILIES == ("tau2", "boson")


@pytest.mark.parametrize("family", ["tau2", "boson"])
def test_runs_record_their_family_and_the_plateau_reference(family):
    cam = make_camera(family, unit=P.UNIT, size=(16, 12))
    run = P.calibration_session(cam, P.SESSION_SEED, True)
    assert run.session.attrs["preset"] == family == run.family
    assert run.session.attrs["unit"] == P.UNIT
    # the reference of the methods that take one: the settled FPA of the 25 °C plateau
    ref = P.plateau_fpa_c(run.session)
    assert abs(ref - cam.thermal.steady_fpa_c(P.PLATEAU_AMBIENT_C)) < 0.6
    cal = fit_calibration(run.session, "two-point", fpa_ref_c=ref)
    assert cal.info["preset"] == family
    held = P.held_out_run(cam, P.HELD_OUT_SEED, True)
    assert held.session.attrs["preset"] == family
    assert set(np.unique(held.part)) == {0, 1}
    # shutter closures every 180 s of each recording, at the camera's own frames' size
    assert [s["frames"].shape[1:] for s in held.shutter] == [(12, 16)] * 2
    assert all(np.all(np.diff(s["time_s"]) > 0) for s in held.shutter)
    # the truth: the grey blackbody (reflecting the chamber) seen in the camera's own band
    s = held.session
    np.testing.assert_allclose(held.truth_c, radiance_temperature_c(
        s.blackbody_c, s.ambient_c, s.attrs["blackbody_emissivity"], cam.band))
    warmer = s.blackbody_c > s.ambient_c + 1
    assert np.all((held.truth_c < s.blackbody_c)[warmer])
    assert np.all(np.abs(held.truth_c - s.blackbody_c) < 1.5)


def test_every_method_is_fitted_or_refused_with_a_reason_and_scored(tiny):
    assert len(tiny["rows"]) == len(CALIBRATION_METHODS) * 4
    for r in tiny["rows"]:
        assert r["method"] in CALIBRATION_METHODS
        if "refused" in r:
            assert isinstance(r["refused"], str) and r["refused"]
            continue
        assert 0 <= r["scored_frames"] <= r["frames"]
        assert 0.0 <= r["flagged_fraction"] <= 1.0
        assert r["scored_frames"] == round(r["frames"] * (1 - r["flagged_fraction"]))
        assert r["non_finite"] == 0
        if r["scored_frames"]:
            assert r["mae_c"] >= 0 and r["p99_abs_c"] >= abs(r["bias_c"]) - 1e-6
    # the polynomial is fitted on every family; it scores the frames inside its FPA range only
    for fit_on in P.FAMILIES:
        for on in P.FAMILIES:
            r = _row(tiny, "polynomial", fit_on, on)
            lo, hi = r["fpa_range_c"]
            assert hi - lo > 25 and r["scored_frames"] > 0.8 * r["frames"]
    # two-point at one FPA: most of a 5→40 °C run lies outside its range, and is flagged
    assert _row(tiny, "two-point", "tau2", "tau2")["flagged_fraction"] > 0.8


def test_own_physics_is_sane_and_the_other_family_is_far_off(tiny):
    for family in P.FAMILIES:
        own = _row(tiny, "polynomial", family, family)
        assert own["mae_slow_ramp_c"] < 1.0, family  # slow drift: the polynomial's domain
        other = next(f for f in P.FAMILIES if f != family)
        cross = _row(tiny, "polynomial", family, other)
        own_other = _row(tiny, "polynomial", other, other)
        assert cross["mae_c"] > 5.0 and cross["mae_c"] > 5 * own_other["mae_c"], family
    # tau2's own polynomial on its settled frames: the accuracy it was designed for
    assert _row(tiny, "polynomial", "tau2", "tau2")["mae_stable_c"] < 0.5
    # the method that follows the FPA rate (tau2's transient) stays accurate on tau2 throughout
    assert _row(tiny, "lin-level", "tau2", "tau2")["mae_c"] < 0.3


def _fake_network():
    from thermocal.evaluation.network import KPN_ROW
    from thermocal.evaluation.references import FAMILY_ROW

    def rows(on):
        out = [{"row": KPN_ROW, "fitted_on": "tau2", "mae_c": 0.5 if on == "tau2" else 4.0},
               {"row": P.OWN_TWO_POINT_ROW, "fitted_on": P.OWN, "mae_c": 0.1}]
        out += [{"row": FAMILY_ROW, "fitted_on": f, "mae_c": 0.8 if f == on else 5.0}
                for f in P.FAMILIES]
        return out

    return {"families": {on: {"rows": rows(on), "network_refused": None} for on in P.FAMILIES}}


def test_the_summary_table_has_four_columns_and_marks_what_does_not_exist(tiny):
    from thermocal.estimation.registry import ESTIMATORS

    rows = P.summary_rows({"calibration": tiny, "network": _fake_network()})
    assert all(len(r["cells"]) == len(P.COLUMNS) == 4 for r in rows)
    names = [r["method"] for r in rows]
    for name in CALIBRATION_METHODS:
        assert f"calibration `{name}`" in names
    for name in ESTIMATORS:  # the networks, and `mean` / `calibration` through a two-point
        assert any(f"`{name}`" in n for n in names), name
    kpn = next(r for r in rows if "`kpn`" in r["method"])
    assert kpn["cells"] == ["0.50", "4.00", "not trained", "not trained"]
    own = next(r for r in rows if "own two-point" in r["method"])
    assert own["cells"] == ["0.10", "n/a (own unit)", "0.10", "n/a (own unit)"]
    floor = next(r for r in rows if r["method"].startswith("(floor)"))
    assert floor["cells"] == ["0.80", "5.00", "0.80", "5.00"]
    poly = next(r for r in rows if r["method"] == "calibration `polynomial`")
    assert float(poly["cells"][1]) > 5 * float(poly["cells"][2])  # tau2 → boson vs boson's own
    text = P.report({"machine": "test", "quick": True, "calibration": tiny})
    assert "| method | tau2 → tau2 | tau2 → boson | boson → boson | boson → tau2 |" in text


@pytest.mark.slow
def test_the_quick_suite_runs_end_to_end(tmp_path, capsys):
    out = tmp_path / "physics.json"
    P.main(["--quick", "--json", str(out)])
    text = capsys.readouterr().out
    res = json.loads(out.read_text())
    assert res["quick"] and res["machine"] in text
    fams = res["network"]["families"]
    assert set(fams) == set(P.FAMILIES)
    for on, d in fams.items():
        assert d["network_ran"] and d["bursts"] == 5, on
        kpn = next(r for r in d["rows"] if r["row"].startswith("KPN"))
        assert len(kpn["per_burst_mae_c"]) == 5
    kpn_row = next(r for r in res["summary"] if "`kpn`" in r["method"])
    assert kpn_row["cells"][2:] == ["not trained", "not trained"]
    # trained on tau2 only: the network is worse on boson bursts than on tau2's
    assert float(kpn_row["cells"][1]) > float(kpn_row["cells"][0])
    assert "### 3. Summary for README" in text


def test_the_other_lags_section_reports_each_variant():
    fake = [{"family": "boson", "thermal": {"tau_optics_s": 600.0},
             "methods": {m: [1.0, 0.5, 1.5] for m in P.LAG_METHODS}}]
    text = P.report({"machine": "test", "quick": True, "lag_variants": fake})
    assert "### 4. Other lags" in text
    assert "| boson | tau_optics 600 s | 1.00 / 0.50 / 1.50 | 1.00 / 0.50 / 1.50 |" in text
    assert len(P.LAG_VARIANTS) == 3 and "lin-lag" in P.LAG_METHODS
