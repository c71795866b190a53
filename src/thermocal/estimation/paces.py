"""A recording's FPA pace at each frame, as an estimator's calibration judges it (numpy only).

A burst's fraction of a second cannot show how the FPA temperature was changing; its recording
can. ``thermocal flight`` and ``thermocal estimate`` both take a burst's pace
(:class:`~thermocal.estimation.base.FpaPace`) from here, so that the same frames are judged the
same way whichever command reads them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from thermocal.calibration.dataset import lagged_rate, recording_fpa_rates, recording_still_time
from thermocal.calibration.report import PACE_LAG_S, fpa_swings, pace_stays, stillness_band

__all__ = ["PACE_KEYS", "pace_at", "recording_paces"]

#: The series :func:`recording_paces` gives, each a keyword of
#: :func:`~thermocal.estimation.pipeline.estimate` (one frame's value, :func:`pace_at`).
PACE_KEYS = ("fpa_rate_c_per_min", "fpa_lagged_rate_c_per_min", "fpa_still_s",
             "fpa_lag_rates_c_per_min", "fpa_sustained_s", "fpa_swing_c")


def recording_paces(fpa_c: Any, time_s: Any, paces: dict[str, Any],
                    rate_lags_s: tuple[float, ...] = ()) -> dict[str, np.ndarray | None]:
    """A recording's pace history, frame by frame ``(M,)``, for a calibration whose report
    holds ``paces`` (an estimator's ``fpa_paces``; empty: a method with no pace to judge) and
    which remembers the FPA's rate through ``rate_lags_s`` (s; an estimator's
    ``rate_lags_s``, ``()``: none):

    - ``fpa_rate_c_per_min``: the FPA rate, °C/min
      (:func:`~thermocal.calibration.dataset.recording_fpa_rates`);
    - ``fpa_lagged_rate_c_per_min``: that rate through the lag of the report's paces
      (``lag_s``), °C/min;
    - ``fpa_still_s``: how long the FPA had held still within the band of the report's
      ``still`` (or ``settling``: a still camera's σ takes its session's last drift), s
      (:func:`~thermocal.calibration.dataset.recording_still_time`);
    - ``fpa_lag_rates_c_per_min``: the rate through each of ``rate_lags_s``, °C/min
      ``(M, K)``, started steady at the recording's first frame (the history ``lin-lag``'s
      lag terms need; a burst alone would start them steady at itself);
    - ``fpa_sustained_s``: how long the FPA rate had stayed at its pace, s
      (:func:`~thermocal.calibration.report.pace_stays`), for a report that holds its
      session's stays (``sustained``: a memoryless method's);
    - ``fpa_swing_c``: how far the FPA had run one way without pause, °C, signed
      (:func:`~thermocal.calibration.report.fpa_swings`), for a report that holds its
      session's runs (``swing``: a method with memory's).

    Each None where it cannot be known: without FPA temperatures or frame times, for a recording
    too short to show its rate, for frame times that do not increase, for a constant FPA series
    (one value given for the whole recording, ``--fpa-c``: no history measured; a lin-lag
    burst would otherwise take a steady history it never had, σ 8× too small), or without
    such a calibration."""
    out: dict[str, np.ndarray | None] = dict.fromkeys(PACE_KEYS)
    if fpa_c is None or np.ptp(np.asarray(fpa_c, np.float64)) == 0:
        return out
    rates = out["fpa_rate_c_per_min"] = recording_fpa_rates(fpa_c, time_s)
    if (rates is None or time_s is None
            or np.any(np.diff(np.asarray(time_s, np.float64)) <= 0)):
        return out
    if rate_lags_s:
        out["fpa_lag_rates_c_per_min"] = np.stack(
            [lagged_rate(rates, time_s, float(tau)) for tau in rate_lags_s], axis=1)
    if not paces:
        return out
    band = stillness_band(paces)
    out["fpa_lagged_rate_c_per_min"] = lagged_rate(rates, time_s, float(paces["lag_s"]))
    if band is not None:
        out["fpa_still_s"] = recording_still_time(fpa_c, time_s, band_c=band,
                                                  max_gap_s=PACE_LAG_S)
    if paces.get("sustained"):
        out["fpa_sustained_s"] = pace_stays(
            rates, time_s, band_c_per_min=paces["sustained"]["band_c_per_min"])
    if paces.get("swing"):
        out["fpa_swing_c"] = fpa_swings(fpa_c, rates, time_s,
                                        band_c_per_min=paces["swing"]["band_c_per_min"])
    return out


def pace_at(paces: dict[str, Any], time_s: Any, k: int) -> dict[str, Any]:
    """Frame ``k``'s pace from a recording's :func:`recording_paces` (``paces``, its
    :data:`PACE_KEYS`; a missing or None series: not known) and how long after the recording's
    first frame it was taken (``time_s``, s; None: not known), as
    :func:`~thermocal.estimation.pipeline.estimate`'s keywords: ``fpa_rate_c_per_min``,
    ``fpa_lagged_rate_c_per_min``, ``fpa_still_s``, ``fpa_sustained_s``, ``fpa_swing_c``
    (floats),
    ``fpa_lag_rates_c_per_min`` (``(K,)``) and ``time_since_start_s``."""
    out: dict[str, Any] = {}
    for name in PACE_KEYS:
        series = paces.get(name)
        out[name] = (None if series is None
                     else series[k] if np.ndim(series) > 1 else float(series[k]))
    out["time_since_start_s"] = None if time_s is None else float(time_s[k] - time_s[0])
    return out
