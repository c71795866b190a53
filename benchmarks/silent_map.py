"""Where `thermocal correct` is wrong beyond its σ without saying so: a map of silent frames.

A helper's audit (2026-11-29, twenty-third session), kept so that its figures can be rerun
(README's Limitations, benchmarks/RESULTS.md): per camera family, each method is calibrated on
the default steps session of one unit (seed 0); each held-out protocol of the same unit (other
seeds) is written as a recording and run through `thermocal correct REC --calibration C --out
T --sigma-out S`, without and with --force. A silent frame: |mean signed error| > 1 °C and
> 2 × its median σ, in output not refused (also counted: forced_paces.py's definition, mean
|error| instead of |mean error|). The same pattern as `benchmarks/forced_paces.py`.

Run (2 cores: about 90 s per family for whole runs, 10–12 min per clip phase):

    python benchmarks/silent_map.py --out OUT [--unit 101] [--presets tau2,boson]
    python benchmarks/silent_map.py --out OUT --clips        # 20- and 60-min clips, unforced
    python benchmarks/silent_map.py --out OUT --held-bb 20:60:10   # scenes inside the range

Writes OUT/results_<presets>.json and OUT/frames_<preset>_<method>_<protocol>.npz (per-frame
error, σ, FPA, rate), and prints a table and the clusters of silent frames.
"""

import argparse
import contextlib
import io
import json
import sys
import time
from pathlib import Path

import numpy as np
import tifffile

from thermocal.calibration.dataset import prepare_chamber, recording_fpa_rates
from thermocal.cli import main as thermocal
from thermocal.io.chamber import read_chamber
from thermocal.io.recording import Recording, write_recording

METHODS = ("polynomial", "lin", "lin-level", "lin-lag", "wolf2016")
# name: (profile, ambient A:B, seed, extra args)
PROTOCOLS = {
    "saw10-40": ("sawtooth", "10:40", 7, []),      # starts low, rises first
    "saw40-10": ("sawtooth", "40:10", 8, []),      # starts high, falls first
    "saw20-35": ("sawtooth", "20:35", 9, []),      # narrow, starts mid-low
    "saw35-15": ("sawtooth", "35:15", 10, []),     # starts mid-high, falls first
    "ramp10-40": ("ramp", "10:40", 11, []),        # rise 60 min then hold 10 min
    "ramp40-10": ("ramp", "40:10", 12, []),        # fall 60 min then hold 10 min
    "const25": ("constant", "25:25", 13, ["--duration-min", "120"]),
    "steps-s14": ("steps", "10:40", 14, []),       # same protocol as calibration, other seed
    "steps40-10": ("steps", "40:10", 15, []),      # down-steps
    "self": None,                                   # control: the calibration session itself
    "ramp10-40-slow": ("ramp", "10:40", 16, ["--rate-c-per-min", "0.25"]),
    "ramp10-40-fast": ("ramp", "10:40", 17, ["--rate-c-per-min", "1.0"]),
    "ramp20-30": ("ramp", "20:30", 18, []),
    "saw10-40-slow": ("sawtooth", "10:40", 19, ["--rate-c-per-min", "0.25"]),
    "steps15-40": ("steps", "15:40", 20, []),      # the same 5 °C grid, from 15 °C
    "steps12-37": ("steps", "12:37", 21, []),      # plateaus between the session's
    "const10": ("constant", "10:10", 22, ["--duration-min", "60"]),
    "const40": ("constant", "40:40", 23, ["--duration-min", "60"]),
}


def run(*args):
    """thermocal ARGS in-process: (exit code, combined output)."""
    said = io.StringIO()
    code = 0
    try:
        with contextlib.redirect_stdout(said), contextlib.redirect_stderr(said):
            thermocal([str(a) for a in args])
    except SystemExit as exc:
        code = 0 if exc.code is None else exc.code
    return code, said.getvalue()


def trend(x, t, thr):
    """+1/-1/0 per frame from the local slope of x (per min) with threshold thr."""
    d = np.gradient(x, t) * 60.0
    return np.where(d > thr, 1, np.where(d < -thr, -1, 0))


def since_change(tr, t):
    """For each frame: minutes since the current trend segment began, and previous trend."""
    n = tr.size
    start = np.zeros(n, int)
    prev = np.full(n, 9)
    s, p = 0, 9
    for i in range(1, n):
        if tr[i] != tr[i - 1]:
            p, s = tr[i - 1], i
        start[i], prev[i] = s, p
    return (t - t[start]) / 60.0, prev


WORD = {1: "rising", -1: "falling", 0: "holding", 9: "start"}


def clusters(mask, gap=2):
    idx = np.flatnonzero(mask)
    out = []
    for i in idx:
        if out and i - out[-1][1] <= gap + 1:
            out[-1][1] = i
        else:
            out.append([i, i])
    return out


def reason_keys(msg):
    """Short tags for the reasons of a refusal / forced warning."""
    import re
    tags = []
    for k, pat in (("paces", r"paces (its chamber session never held|more than)"),
                   ("still-unknown", "still throughout its recording"),
                   ("still-longer", r"held (the FPA )?still (for )?longer|longer than they held"),
                   ("scene", "the scene spans"), ("fpa-range", r"FPA temperature \S+ is outside"),
                   ("rate", "faster than the"), ("imprint", "another camera"),
                   ("no-sigma", "no σ|no uncertainty")):
        if re.search(pat, msg):
            tags.append(k)
    return tags


def score(T, S, truth):
    n = T.shape[0]
    e = (T - truth[:, None, None]).reshape(n, -1)
    s = S.reshape(n, -1)
    ok = np.isfinite(e) & np.isfinite(s)
    fe = np.array([e[i][ok[i]].mean() for i in range(n)])
    fs = np.array([np.median(s[i][ok[i]]) for i in range(n)])
    sil = (np.abs(fe) > 1.0) & (np.abs(fe) > 2 * fs)
    return fe, fs, sil


def clips(a):
    """Phase 2: windows of each held-out recording corrected WITHOUT --force; in those not
    refused, count silent frames (the tool said nothing)."""
    out = Path(a.out)
    rows = []
    t0 = time.time()
    for preset in a.presets.split(","):
        d = out / preset
        for pname in a.protocols.split(","):
            h5 = d / ("steps.h5" if PROTOCOLS[pname] is None else f"held_{pname}.h5")
            if not h5.exists():
                continue
            held = read_chamber(h5)
            truth = prepare_chamber(h5).scene_c
            t = np.asarray(held.time_s, float)
            fpa = np.asarray(held.fpa_c, float)
            rate = recording_fpa_rates(fpa, t)
            amb = np.asarray(held.ambient_c, float)
            frames = np.asarray(held.frames)
            dt = t[1] - t[0]
            wins = []
            for L_min, step_min in ((20, 3), (60, 10)):
                L, st = int(round(L_min * 60 / dt)), int(round(step_min * 60 / dt))
                wins += [(i, i + L) for i in range(0, t.size - L + 1, st)]
            for m in a.methods.split(","):
                cal = d / f"{m}.h5"
                if not cal.exists():
                    continue
                n_ok = n_sil = 0
                for i0, i1 in wins:
                    rec, tt, ss = d / "clip.tiff", d / "ct.tiff", d / "cs.tiff"
                    write_recording(rec, Recording(frames[i0:i1], fpa_c=fpa[i0:i1],
                                                   time_s=t[i0:i1]))
                    for f in (tt, ss):
                        f.unlink(missing_ok=True)
                    code, msg = run("correct", rec, "--calibration", cal, "--out", tt,
                                    "--sigma-out", ss)
                    row = dict(preset=preset, method=m, proto=pname, t0_min=t[i0] / 60,
                               t1_min=t[i1 - 1] / 60, refused=code != 0,
                               keys=reason_keys(msg) if code else [])
                    if code == 0:
                        n_ok += 1
                        fe, fs, sil = score(tifffile.imread(tt), tifffile.imread(ss),
                                            truth[i0:i1])
                        row.update(silent=int(sil.sum()), mae=float(np.mean(np.abs(fe))),
                                   med_sigma=float(np.median(fs)))
                        if sil.any():
                            n_sil += 1
                            k = np.flatnonzero(sil) + i0
                            row["silent_frames"] = [dict(
                                t_min=float(t[j] / 60), fpa=float(fpa[j]), rate=float(rate[j]),
                                amb=float(amb[j]), bb=float(held.blackbody_c[j]),
                                err=float(fe[j - i0]), sigma=float(fs[j - i0]))
                                for j in k]
                    rows.append(row)
                print(f"[{time.time() - t0:5.0f}s] clips {preset} {m} {pname}: {len(wins)} windows,"
                      f" {n_ok} not refused, {n_sil} of those with silent frames", flush=True)
                (out / "clips.json").write_text(json.dumps(rows, indent=0))
    (out / "clips.json").write_text(json.dumps(rows, indent=0))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--unit", type=int, default=101)
    ap.add_argument("--size", default="80x64")
    ap.add_argument("--out", default="silent_out")
    ap.add_argument("--presets", default="tau2,boson")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--protocols", default=",".join(PROTOCOLS))
    ap.add_argument("--clips", action="store_true", help="phase 2 (after phase 1)")
    ap.add_argument("--held-bb", default=None,
                    help="--blackbody-c for the held-out sessions only (e.g. 20:60:10: a scene "
                    "inside the calibrated range, so the scene-range check cannot fire)")
    a = ap.parse_args()
    if a.clips:
        return clips(a)
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    t0 = time.time()
    for preset in a.presets.split(","):
        d = out / preset
        d.mkdir(exist_ok=True)
        cam = ["--preset", preset, "--unit", a.unit, "--size", a.size]
        code, msg = run("simulate", "chamber", d / "steps.h5", *cam)
        assert code == 0, msg
        cal_msgs = {}
        for m in a.methods.split(","):
            code, msg = run("calibrate", d / "steps.h5", "--method", m, "--out", d / f"{m}.h5")
            if code and m == "wolf2016" and "--fpa-ref-c" in msg:  # pick the middle plateau
                import re
                found = re.search(r"plateaus \(([^)]*)\)", msg).group(1)
                plats = [float(x.split()[0]) for x in found.split(", ")]
                ref = plats[len(plats) // 2]
                print(f"[{preset} {m}] default refused; retry --fpa-ref-c {ref}", flush=True)
                msg = f"(default refused: {msg.strip()})\n"
                code, msg2 = run("calibrate", d / "steps.h5", "--method", m, "--fpa-ref-c", ref,
                                 "--out", d / f"{m}.h5")
                msg += msg2
            cal_msgs[m] = msg
            (d / f"cal_{m}.txt").write_text(msg)
            if code:
                print(f"[{preset} {m}] calibrate failed: {msg}", flush=True)
        for pname in a.protocols.split(","):
            h5 = d / f"held_{pname}.h5"
            if PROTOCOLS[pname] is None:
                h5, code, msg = d / "steps.h5", 0, ""
            else:
                prof, amb, seed, extra = PROTOCOLS[pname]
                code, msg = run("simulate", "chamber", h5, *cam, "--ambient-profile", prof,
                                "--ambient-c", amb, "--seed", seed, *extra,
                                *(["--blackbody-c", a.held_bb] if a.held_bb else []))
            if code:
                print(f"[{preset} {pname}] simulate failed: {msg}", flush=True)
                continue
            held = read_chamber(h5)
            rec = d / f"held_{pname}.tiff"
            write_recording(rec, Recording(held.frames, fpa_c=held.fpa_c, time_s=held.time_s))
            truth = prepare_chamber(h5).scene_c
            t = np.asarray(held.time_s, float)
            fpa = np.asarray(held.fpa_c, float)
            rate = recording_fpa_rates(fpa, t)
            amb_c = np.asarray(held.ambient_c, float)
            atr = trend(amb_c, t, 0.05)
            ftr = np.where(rate > 0.05, 1, np.where(rate < -0.05, -1, 0))
            a_since, a_prev = since_change(atr, t)
            f_since, f_prev = since_change(ftr, t)
            for m in a.methods.split(","):
                cal = d / f"{m}.h5"
                if not cal.exists():
                    continue
                tt, ss = d / "t.tiff", d / "s.tiff"
                for f in (tt, ss):
                    f.unlink(missing_ok=True)
                code_u, msg_u = run("correct", rec, "--calibration", cal, "--out", tt,
                                    "--sigma-out", ss)
                refused = code_u != 0
                unforced_ok = None
                if not refused:
                    unforced_ok = (tifffile.imread(tt), tifffile.imread(ss))
                code_f, msg_f = run("correct", rec, "--calibration", cal, "--force",
                                    "--out", tt, "--sigma-out", ss)
                row = dict(preset=preset, method=m, proto=pname, refused=refused,
                           keys=reason_keys(msg_u if refused else msg_f),
                           refuse_code=code_u,
                           refuse_msg=msg_u.strip() if refused else "",
                           unforced_msg="" if refused else msg_u.strip(),
                           forced_code=code_f, forced_msg=msg_f.strip())
                if code_f != 0:
                    print(f"[{preset} {m} {pname}] forced correct failed: {msg_f}", flush=True)
                    results.append(row)
                    continue
                T, S = tifffile.imread(tt), tifffile.imread(ss)
                if unforced_ok is not None:  # the unforced output is what the user gets
                    row["unforced_equals_forced"] = bool(
                        np.allclose(unforced_ok[0], T, equal_nan=True)
                        and np.allclose(unforced_ok[1], S, equal_nan=True))
                n = T.shape[0]
                e = (T - truth[:, None, None]).reshape(n, -1)
                s = S.reshape(n, -1)
                ok = np.isfinite(e) & np.isfinite(s)
                ae = np.abs(e)
                fe = np.array([e[i][ok[i]].mean() for i in range(n)])        # signed mean
                fae = np.array([ae[i][ok[i]].mean() for i in range(n)])      # mean |e|
                fs = np.array([np.median(s[i][ok[i]]) for i in range(n)])
                sil = (np.abs(fe) > 1.0) & (np.abs(fe) > 2 * fs)
                sil_b = (fae > 1.0) & (fae > 2 * fs)
                row.update(frames=n, mae=float(ae[ok].mean()),
                           w1=float(100 * np.mean(ae[ok] <= s[ok])),
                           w2=float(100 * np.mean(ae[ok] <= 2 * s[ok])),
                           med_sigma=float(np.median(s[ok])),
                           silent=int(sil.sum()), silent_bench=int(sil_b.sum()))
                cl = []
                for i0, i1 in clusters(sil):
                    sl = slice(i0, i1 + 1)
                    cl.append(dict(
                        n=int(sil[sl].sum()), t_min=[t[i0] / 60, t[i1] / 60],
                        fpa=[float(fpa[sl].min()), float(fpa[sl].max())],
                        rate=[float(rate[sl].min()), float(rate[sl].max())],
                        amb=[float(amb_c[i0]), float(amb_c[i1])],
                        amb_trend=WORD[int(atr[i0])], amb_since_min=float(a_since[i0]),
                        amb_prev=WORD[int(a_prev[i0])],
                        fpa_trend=WORD[int(ftr[i0])], fpa_since_min=float(f_since[i0]),
                        fpa_prev=WORD[int(f_prev[i0])],
                        err=[float(fe[sl].min()), float(fe[sl].max())],
                        sigma=[float(fs[sl].min()), float(fs[sl].max())],
                        bb=sorted({float(x) for x in np.asarray(held.blackbody_c)[sl][sil[sl]]})))
                row["clusters"] = cl
                np.savez_compressed(out / f"frames_{preset}_{m}_{pname}.npz", t=t, fpa=fpa,
                                    rate=rate, amb=amb_c, bb=np.asarray(held.blackbody_c),
                                    truth=truth, err=fe, abserr=fae, sigma=fs, silent=sil)
                results.append(row)
                print(f"[{time.time() - t0:5.0f}s] {preset:5s} {m:10s} {pname:10s} "
                      f"refused={'yes' if refused else 'no '} n={n} MAE={row['mae']:.2f} "
                      f"w1={row['w1']:.1f} w2={row['w2']:.1f} medσ={row['med_sigma']:.2f} "
                      f"silent={row['silent']} (bench def {row['silent_bench']})", flush=True)
                for c in cl:
                    print(f"      {c['n']:3d} fr t={c['t_min'][0]:.0f}-{c['t_min'][1]:.0f} min "
                          f"FPA {c['fpa'][0]:.1f}-{c['fpa'][1]:.1f} rate {c['rate'][0]:+.2f}.."
                          f"{c['rate'][1]:+.2f} amb {c['amb_trend']} {c['amb_since_min']:.0f} min"
                          f" (after {c['amb_prev']}); FPA {c['fpa_trend']} "
                          f"{c['fpa_since_min']:.0f} min (after {c['fpa_prev']}) "
                          f"err {c['err'][0]:+.2f}..{c['err'][1]:+.2f} σ {c['sigma'][0]:.2f}.."
                          f"{c['sigma'][1]:.2f} bb {c['bb']}", flush=True)
            name = f"results_{a.presets.replace(',', '_')}.json"
            (out / name).write_text(json.dumps(results, indent=1))
    (out / f"results_{a.presets.replace(',', '_')}.json").write_text(json.dumps(results, indent=1))
    print(f"done in {time.time() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    sys.exit(main())
