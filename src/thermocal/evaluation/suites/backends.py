"""How fast each inference backend runs the shipped network, against the CPU's peak (issue 21).

One 336×256 burst of N = 7 (``tau2`` unit 101 over the held-out aerial scene, FPA 35 °C,
registered with the true homographies) is prepared once by the estimation pipeline; then the
network alone (:func:`~thermocal.nn.infer.run_network`: input planes, the network, radiance →
temperature) runs on it through each installed backend (:mod:`thermocal.nn.backends`) on 1 and
2 threads, interleaved round by round so that a busy moment of the machine falls on every
backend alike. Beside them, as the baseline of issue 21, the same network as PyTorch eager ran
it before eq. 11 was folded (:data:`BEFORE`: the head's ``N·K²`` kernels formed and applied by
:func:`~thermocal.nn.model.apply_kernels`). Reported: the median time of :data:`ROUNDS` runs
after a warm-up (the first call, which for ONNX Runtime and OpenVINO exports and compiles the
graph, apart), its ratio to PyTorch eager on as many threads and to that baseline, the largest
difference from PyTorch's temperatures (°C), and the multiply-add rate against the peak of this
CPU. Then each backend with two bursts at once, each on one thread (a runner for two callers,
as ``thermocal flight`` runs its groups, :func:`~thermocal.pipeline.flight.pivot_workers`):
the wall time per burst, against the baseline on two threads one burst at a time.

**The peak.** Two figures: the rate of a large float32 matrix product (``torch.mm`` of
:data:`GEMM_SIDE`², MKL/oneDNN: the practical peak of a dense kernel on these cores), and the
theoretical one, cores × clock (``/proc/cpuinfo``) × FMA lanes per cycle (:func:`fma_per_cycle`:
two 256-bit FMA pipes, 16 float32 multiply-adds, on AMD Zen 2-4 and Intel cores with AVX2; two
512-bit ones, 32, on an Intel core with AVX-512, as server Xeons have) at
the clock ``/proc/cpuinfo`` names, which is the nominal one: cores that boost run above it, so
that a rate over 100 % of it says the clock was higher, not that the count is wrong. The
network's multiply-adds are counted by :func:`~thermocal.nn.model.count_macs` (convolutions and
eq. 11 as the network computes it; forming the kernels takes 0.02 % fewer, 0.5 % of the
kernel step's).

Run: ``python -m thermocal.evaluation.suites.backends [--quick] [--json OUT]``.
"""

from __future__ import annotations

import time

import numpy as np

#: Timed runs per backend and thread count (``--quick``: 3).
ROUNDS = 9
#: Side of the matrix product that measures the practical peak.
GEMM_SIDE = 2048
#: float32 multiply-adds per cycle per core: two 256-bit FMA units (AVX2; Zen 4 runs AVX-512 on
#: them too); an Intel core with AVX-512 has two 512-bit ones (:func:`fma_per_cycle`: on such a
#: Xeon the network ran at 113-156 % of the AVX2 figure, which is no peak).
FMA_PER_CYCLE = 16


def fma_per_cycle(cpuinfo: str | None = None) -> int:
    """float32 multiply-adds per cycle per core of this CPU (``cpuinfo``: the text of
    /proc/cpuinfo, read when None): 32 for an Intel core with ``avx512f``, else
    :data:`FMA_PER_CYCLE` (some Xeon Silver and Bronze parts have one 512-bit unit, 16 alike:
    there the theoretical figure is twice theirs)."""
    if cpuinfo is None:
        try:
            with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
                cpuinfo = f.read()
        except OSError:
            return FMA_PER_CYCLE
    flags = next((line for line in cpuinfo.splitlines() if line.startswith("flags")), "")
    intel = "GenuineIntel" in cpuinfo
    return 2 * FMA_PER_CYCLE if intel and " avx512f" in f" {flags.split(':')[-1]}" else \
        FMA_PER_CYCLE
THREADS = (1, 2)
#: Bursts at once in the last rows, each on one thread.
PAIR = 2
#: The baseline's row name: PyTorch eager with eq. 11's kernels formed (the network until the
#: kernel step was folded, :meth:`thermocal.nn.model.KernelHead.kernel_sum`;
#: :func:`~thermocal.nn.model.with_formed_kernels`).
BEFORE = "torch, kernels formed (before)"


def _clock_ghz() -> float | None:
    """The CPU clock /proc/cpuinfo reports, GHz (None elsewhere)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            return float(next(line.split(":")[1] for line in f if line.startswith("cpu MHz"))) / 1e3
    except (OSError, StopIteration, ValueError):
        return None


def _burst():
    from thermocal.camera.presets import make_camera
    from thermocal.estimation.pipeline import estimate
    from thermocal.nn.infer import NetworkEstimator
    from thermocal.scenes.builtin import load_builtin_scene
    from thermocal.simulate.flight import simulate_flight

    cam = make_camera("tau2", unit=101, size=(336, 256))
    fl = simulate_flight(load_builtin_scene("aerial"), cam, n_frames=7, motion="walk",
                         fpa_c=35.0, seed=0)
    captured = {}

    class Capture(NetworkEstimator):  # keeps the prepared burst the network is given
        def estimate(self, burst):
            captured["burst"] = burst
            return super().estimate(burst)

    base = NetworkEstimator.from_file("kpn")
    estimate(fl.frames, Capture(base.model, base.norm), fpa_c=fl.fpa_c,
             homographies=fl.homographies, pivot=fl.pivot)
    return base, captured["burst"]


def gemm_rate(threads: int, side: int = GEMM_SIDE, rounds: int = 5) -> float:
    """Multiply-adds per second of a ``side``² float32 matrix product on ``threads`` threads."""
    import torch

    torch.set_num_threads(threads)
    a = torch.rand(side, side)
    b = torch.rand(side, side)
    torch.mm(a, b)
    times = []
    for _ in range(rounds):
        t = time.perf_counter()
        torch.mm(a, b)
        times.append(time.perf_counter() - t)
    return side**3 / float(np.median(times))


def run(*, quick: bool) -> dict:
    import torch

    from thermocal.nn import backends
    from thermocal.nn.infer import _to_model_order, run_network
    from thermocal.nn.model import count_macs, with_formed_kernels
    from thermocal.nn.runners import make_runner

    base, burst = _burst()
    model, norm = base.model, base.norm
    warped = _to_model_order(burst.warped, burst.pivot)
    valid = _to_model_order(burst.valid, burst.pivot)
    macs = count_macs(model, *warped.shape[1:])
    names = [b for b in backends.BACKENDS if backends.installed(b)] + [BEFORE]
    before = with_formed_kernels(model)
    rounds = 3 if quick else ROUNDS
    rows, reference = [], {}
    for threads in THREADS:
        runners, first = {}, {}
        for name in names:
            torch.set_num_threads(threads)
            t = time.perf_counter()
            runners[name] = (make_runner(before, "torch", threads=threads) if name == BEFORE
                             else make_runner(model, name, threads=threads))
            out = run_network(model, norm, warped, valid, burst.fpa_c, runner=runners[name])
            first[name] = time.perf_counter() - t
            reference.setdefault(name, out)
        times: dict[str, list[float]] = {name: [] for name in names}
        for _ in range(rounds):  # interleaved: a busy moment falls on every backend alike
            for name in names:
                torch.set_num_threads(threads)
                t = time.perf_counter()
                run_network(model, norm, warped, valid, burst.fpa_c, runner=runners[name])
                times[name].append(time.perf_counter() - t)
        rows += _rows(names, threads, 1, times, first, reference, macs)
    rows += _rows(names, THREADS[-1], PAIR, *_pairs(names, model, before, norm, warped, valid,
                                                    burst.fpa_c, rounds),
                  reference, macs, baseline=rows[-1]["median_s"] / rows[-1]["vs_before"])
    clock = _clock_ghz()
    cores = backends.default_threads()
    peak = {"gemm_gmac_per_s": {t: gemm_rate(t) / 1e9 for t in THREADS},
            "theoretical_gmac_per_s": None if clock is None else cores * clock * fma_per_cycle(),
            "clock_ghz": clock, "cores": cores, "fma_per_cycle": fma_per_cycle()}
    return {"macs": macs, "rows": rows, "peak": peak, "rounds": rounds,
            "frame": list(warped.shape)}


def _pairs(names: list[str], model, before, norm, warped, valid, fpa_c: float, rounds: int
           ) -> tuple[dict[str, list[float]], dict[str, float]]:
    """Seconds per burst with :data:`PAIR` bursts at once, each on one thread, ``rounds``
    times per backend (interleaved), and each backend's first call (a pair's)."""
    from concurrent.futures import ThreadPoolExecutor

    import torch

    from thermocal.nn.infer import run_network
    from thermocal.nn.runners import make_runner

    torch.set_num_threads(1)
    runners = {name: (make_runner(before, "torch", threads=1, concurrent=PAIR) if name == BEFORE
                      else make_runner(model, name, threads=1, concurrent=PAIR))
               for name in names}
    times: dict[str, list[float]] = {name: [] for name in names}
    first: dict[str, float] = {}
    with ThreadPoolExecutor(PAIR) as pool:
        def pair(name: str) -> float:
            t = time.perf_counter()
            list(pool.map(lambda _: run_network(model, norm, warped, valid, fpa_c,
                                                runner=runners[name]), range(PAIR)))
            return (time.perf_counter() - t) / PAIR

        for name in names:
            first[name] = pair(name) * PAIR
        for _ in range(rounds):
            for name in names:
                times[name].append(pair(name))
    return times, first


def _rows(names: list[str], threads: int, concurrent: int, times: dict[str, list[float]],
          first: dict[str, float], reference: dict[str, np.ndarray], macs: int, *,
          baseline: float | None = None) -> list[dict]:
    """The table's rows of one thread count (``concurrent`` bursts at once): ratios to torch's
    and to ``baseline`` (default: :data:`BEFORE` in the same runs)."""
    eager = float(np.median(times["torch"]))
    baseline = float(np.median(times[BEFORE])) if baseline is None else baseline
    rows = []
    for name in names:
        med = float(np.median(times[name]))
        rows.append({"backend": name, "threads": threads, "concurrent": concurrent,
                     "median_s": med, "min_s": float(np.min(times[name])),
                     "first_call_s": first[name], "vs_torch": med / eager,
                     "vs_before": med / baseline,
                     "max_abs_diff_c": float(np.abs(reference[name] - reference["torch"]).max()),
                     "gmac_per_s": macs / med / 1e9})
    return rows


def report(res: dict, info: dict) -> str:
    from thermocal.evaluation.tables import markdown_table

    peak = res["peak"]
    theory = peak["theoretical_gmac_per_s"]
    cells = []
    for r in res["rows"]:
        gemm = peak["gemm_gmac_per_s"][r["threads"]]
        pair = r.get("concurrent", 1) > 1
        cells.append((r["backend"], f"{r['concurrent']} bursts × 1" if pair else r["threads"],
                      f"{1e3 * r['median_s']:.0f}",
                      f"{1e3 * r['min_s']:.0f}", f"{r['first_call_s']:.2f}",
                      f"{r['vs_torch']:.2f}", f"{r['vs_before']:.2f}",
                      f"{r['max_abs_diff_c']:.1e}",
                      f"{r['gmac_per_s']:.1f}", f"{100 * r['gmac_per_s'] / gemm:.0f} %",
                      "–" if theory is None else
                      f"{100 * r['gmac_per_s'] / (theory * r['threads'] / peak['cores']):.0f} %"))
    header = ("backend", "threads", "median ms (per burst)", "best ms", "first call s",
              "× torch eager", "× eager before (kernels formed; on 2 threads for 2 bursts × 1)",
              "max |Δ| °C vs torch", "G multiply-adds/s",
              "of the matrix product's rate",
              "of the theoretical peak")
    gemm = ", ".join(f"{v:.1f} on {t} thread{'s' if t > 1 else ''}"
                     for t, v in peak["gemm_gmac_per_s"].items())
    return (f"## Inference backends\n\nmachine: {info['machine']}; {info['wall_s']:.0f} s\n\n"
            f"data: the shipped `kpn` on one burst of N = {res['frame'][0]}, "
            f"{res['frame'][2]}×{res['frame'][1]} (`tau2` unit 101, held-out aerial scene, "
            f"FPA 35 °C), the network alone (input planes → temperature), median of "
            f"{res['rounds']} interleaved runs; {res['macs'] / 1e9:.2f} G multiply-adds per "
            f"burst. Peak: a {GEMM_SIDE}² float32 matrix product (torch.mm) runs at {gemm} G "
            "multiply-adds/s; theoretical "
            + ("unknown" if theory is None else
               f"{theory:.0f} G/s = {peak['cores']} cores × {peak['clock_ghz']:.2f} GHz × "
               f"{peak['fma_per_cycle']} float32 FMA per cycle at the nominal clock (boosted "
               "cores run faster: the matrix product's rate is the peak to aim at)")
            + f".\n\n{markdown_table(header, cells)}\n")


def main(argv: list[str] | None = None) -> None:
    from thermocal.bench import suite_main

    suite_main(__doc__, run, report, argv, quick_help="3 runs each.")


if __name__ == "__main__":
    main()
