"""Does a calibration tell frames of another camera? The imprint of its fixed pattern
(:mod:`thermocal.calibration.imprint`; README "Trust", RESULTS.md "Another camera's frames").

Every calibration method is fitted on unit 101 of each family (the physics benchmark's
calibration session, ``--size`` crop) and applied to

- 3-frame walks over the built-in aerial scene and procedural urban and farmland maps, at FPA
  temperatures 15, 30 and 42 °C, of the calibration's own unit (raw, and as the camera gives
  them with its own flat-field correction on:
  :func:`~thermocal.simulate.flight.flat_field_corrected`), another unit of its family (102)
  and two units of the other family (101, 102): the imprint of each frame and its MAE;
- every frame of its own unit's held-out chamber run (the physics benchmark's: a slow ramp and
  hold, a 1 °C/min sawtooth, with the shutter closures of a shutter calibration): the
  calibration's own camera through FPA transients, where its output errs most.

Every calibration is fitted with its cross-validation report, as ``thermocal calibrate`` writes
it, and each walk frame goes through the product's pipeline as ``thermocal estimate --method
calibration`` takes frame k of a recording (its FPA pace from the recording). Prints a Markdown
table per part: the imprint's range (slope; :func:`~thermocal.calibration.imprint.imprint`),
how many frames are refused and how many of those as another camera's (the imprint among the
reasons), what those would have given forced (their MAE, how many of their errors lie within
the σ stated forced and twice it, and how many lay inside every other range: accepted before
the imprint was checked), the MAE of the frames accepted and how many
of those are silent (error above 1 °C and twice the median σ).

    .venv/bin/python benchmarks/another_camera.py [--size 96x72] [--quick]

(``--quick``: the physics benchmark's quick sessions, one FPA temperature; ~1 min.)
"""

import argparse
import warnings
from dataclasses import replace

import numpy as np

from thermocal.bench import machine
from thermocal.calibration.imprint import imprint
from thermocal.calibration.registry import CALIBRATION_METHODS
from thermocal.calibration.report import fit_with_report
from thermocal.camera.presets import PRESETS, make_camera
from thermocal.errors import OutsideDomainError, ThermocalError
from thermocal.estimation.calibrated import PivotCalibration
from thermocal.estimation.paces import pace_at, recording_paces
from thermocal.estimation.pipeline import estimate
from thermocal.evaluation.suites import physics
from thermocal.metrics import sigma_coverage
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import flat_field_corrected, simulate_flight

FPAS_C = (15.0, 30.0, 42.0)
#: The imprint's refusal, among an estimate's reasons.
FOREIGN = "not raw frames of the camera"


def _quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*args, **kwargs)


def _fitted(run: physics.Run) -> dict:
    """Every calibration method fitted with its report on ``run``'s session (the reference FPA
    of those that take one at its 25 °C plateau), ``{name: calibration}``; those the
    protocol refuses left out."""
    ref = physics.plateau_fpa_c(run.session)
    out = {}
    for name, info in CALIBRATION_METHODS.items():
        try:
            out[name] = _quiet(fit_with_report, run.session, name,
                               **({"fpa_ref_c": ref} if info.takes_fpa_ref else {}))[0]
        except ThermocalError:
            continue
    return out


def _walk_rows(cals: dict, family: str, size: tuple[int, int], fpas: tuple[float, ...]
               ) -> list[dict]:
    scenes = {"aerial": load_builtin_scene("aerial")}
    for kind in ("urban", "farmland"):
        scenes[kind] = procedural_scene((512, 512), rng=np.random.default_rng(1), kind=kind)
    cameras = [("own unit", family, physics.UNIT), ("own unit, its FFC on", family,
                                                   physics.UNIT),
               ("another unit", family, physics.UNIT + 1)]
    other = next(f for f in PRESETS if f != family)
    cameras += [("another family", other, physics.UNIT), ("another family", other,
                                                           physics.UNIT + 1)]
    rows = []
    for label, fam, unit in cameras:
        camera = make_camera(fam, unit=unit, size=size)
        flights = [simulate_flight(scene, camera, n_frames=3, motion="walk", fpa_c=fpa, seed=3)
                   for scene in scenes.values() for fpa in fpas]
        if "FFC" in label:
            flights = [replace(fl, frames=flat_field_corrected(camera, fl)) for fl in flights]
        for name, cal in cals.items():
            estimator = PivotCalibration(cal, report_needed=True)
            slopes, accepted_err, forced_err, forced_pairs = [], [], [], []
            refused = foreign = silent = before = 0
            for fl in flights:
                temps = _quiet(cal.apply, fl.frames, fpa_c=fl.fpa_c, time_s=fl.time_s)
                paces = recording_paces(fl.fpa_c, fl.time_s, estimator.fpa_paces,
                                        estimator.rate_lags_s)
                for k in range(fl.frames.shape[0]):
                    got = imprint(cal, fl.frames[k], temps[k], fpa_c=float(fl.fpa_c[k]))
                    slopes.append(np.nan if got is None else got.slope)
                    args = {"fpa_c": fl.fpa_c, "time_s": fl.time_s, "pivot": k,
                            **pace_at(paces, fl.time_s, k)}
                    try:  # as `thermocal estimate` takes a recording's frame k
                        est = _quiet(estimate, fl.frames, estimator, **args)
                    except OutsideDomainError as exc:
                        refused += 1
                        if FOREIGN in str(exc):  # what it would have given, forced
                            foreign += 1
                            forced = _quiet(estimate, fl.frames, estimator, force=True, **args)
                            forced_err.append(float(np.abs(forced.temperature_c
                                                           - fl.truth_c[k]).mean()))
                            if forced.sigma_c is not None:  # the σ it states, grown
                                forced_pairs.append((forced.temperature_c - fl.truth_c[k],
                                                     forced.sigma_c))
                            before += all(FOREIGN in r for r in forced.outside)
                        continue
                    err = np.abs(est.temperature_c - fl.truth_c[k])
                    accepted_err.append(float(err.mean()))
                    silent += int(err.mean() > max(1.0, 2.0 * float(np.median(est.sigma_c))))
            rows.append({"calibration": f"{family} {name}", "frames of": f"{label} ({fam} "
                         f"{unit})", "slopes": slopes, "refused": refused, "foreign": foreign,
                         "silent": silent, "frames": len(slopes),
                         "accepted_mae": accepted_err, "forced_mae": forced_err,
                         "forced_coverage": (sigma_coverage(
                             np.concatenate([e.ravel() for e, _ in forced_pairs]),
                             np.concatenate([v.ravel() for _, v in forced_pairs]))
                             if forced_pairs else None),
                         "before": before})
    return rows


def _held_out_rows(cals: dict, family: str, size: tuple[int, int], quick: bool) -> list[dict]:
    camera = make_camera(family, unit=physics.UNIT, size=size)
    run = physics.held_out_run(camera, physics.HELD_OUT_SEED, quick)
    s = run.session
    rows = []
    for name, cal in cals.items():
        temps, _ = _quiet(physics.apply_run, cal, run)
        slopes, refused = [], 0
        for k in range(s.n_frames):
            c = cal  # a shutter calibration's offsets: those of its part's closures
            if hasattr(cal, "with_shutter") and run.shutter:
                c = cal.with_shutter(**run.shutter[run.part[k]])
            got = imprint(c, s.frames[k], temps[k], fpa_c=float(s.fpa_c[k]),
                          time_s=float(s.time_s[k]))
            slopes.append(np.nan if got is None else got.slope)
            refused += int(got is not None and got.foreign)
        rows.append({"calibration": f"{family} {name}", "frames of": "own unit, held-out "
                     "chamber run", "slopes": slopes, "refused": refused,
                     "frames": len(slopes)})
    return rows


def _span(slopes: list[float]) -> tuple[str, int]:
    s = np.asarray(slopes, dtype=float)
    ok = s[np.isfinite(s)]
    span = f"{ok.min():+.3f} … {np.median(ok):+.3f} … {ok.max():+.3f}" if ok.size else "–"
    return span, int(np.sum(~np.isfinite(s)))


def _table(rows: list[dict]) -> str:
    out = ["| calibration | frames of | imprint (min … median … max) | not judged | "
           "refused | of which as another camera's | those forced: MAE °C (min … max) | "
           "within 1σ / 2σ of the σ stated forced (median σ °C) | "
           "of those, inside every other range | accepted: MAE °C (max) | silent |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        span, unjudged = _span(r["slopes"])
        mae, forced = r["accepted_mae"], r["forced_mae"]
        mae_cell = f"{np.mean(mae):.2f} ({np.max(mae):.2f})" if mae else "–"
        forced_cell = (f"{np.mean(forced):.2f} ({np.min(forced):.2f} … {np.max(forced):.2f})"
                       if forced else "–")
        cov = r.get("forced_coverage")
        forced_cell += (" | –" if cov is None else
                        f" | {100 * cov['within_1sigma']:.0f} / {100 * cov['within_2sigma']:.0f}"
                        f" % ({cov['median_sigma_c']:.1f})")
        out.append(f"| {r['calibration']} | {r['frames of']} | {span} | {unjudged} | "
                   f"{r['refused']} of {r['frames']} | {r['foreign']} | {forced_cell} | "
                   f"{r['before']} | {mae_cell} | {r['silent']} |")
    return "\n".join(out)


def _held_table(rows: list[dict]) -> str:
    out = ["| calibration | frames of | imprint (min … median … max) | not judged | "
           "called another camera's |", "|---|---|---|---|---|"]
    for r in rows:
        span, unjudged = _span(r["slopes"])
        out.append(f"| {r['calibration']} | {r['frames of']} | {span} | {unjudged} | "
                   f"{r['refused']} of {r['frames']} |")
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="96x72", help="crop WxH (default 96x72)")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    w, h = (int(v) for v in args.size.lower().split("x"))
    fpas = (30.0,) if args.quick else FPAS_C
    walks, held = [], []
    for family in PRESETS:
        camera = make_camera(family, unit=physics.UNIT, size=(w, h))
        session = physics.calibration_session(camera, physics.SESSION_SEED, args.quick)
        cals = _fitted(session)
        walks += _walk_rows(cals, family, (w, h), fpas)
        held += _held_out_rows(cals, family, (w, h), args.quick)
    print(f"## Another camera's frames: the imprint of a calibration's pattern\n\n"
          f"machine: {machine()}; `python benchmarks/another_camera.py"
          f"{' --quick' if args.quick else ''} --size {w}x{h}`\n\n{w}×{h}, "
          f"walks of 3 frames over aerial, urban and farmland scenes at FPA "
          f"{', '.join(f'{f:g}' for f in fpas)} °C; calibrations of unit {physics.UNIT}.\n")
    print(_table(walks))
    print("\n### The calibration's own camera through its held-out chamber run\n")
    print(_held_table(held))


if __name__ == "__main__":
    main()
