"""What a chamber session must hold for each calibration method, checked before a fit.

Each method states its needs in the registry (:class:`ProtocolNeeds`, the ``needs`` of
:class:`~thermocal.calibration.registry.CalibrationInfo`): which frames its fit uses, how many
blackbody set points and how many well-spread FPA temperatures they must cover, and what else its
model must see. :func:`check_protocol` reads them against a prepared session
(:func:`~thermocal.calibration.registry.check_session` by method name) and returns a
:class:`ProtocolCheck`: a refusal (one line: what the session lacks and exactly what to record),
warnings (usable but degraded), and the options to fit with (a fallback frame selection).

The frames are described by their FPA stability (:mod:`thermocal.calibration.dataset`): stable
(FPA rate within ±0.05 °C/min), settled (within ±0.5 °C/min), all.
"""

from __future__ import annotations

import ast
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from thermocal.calibration.dataset import (
    MAX_FPA_CONDITION,
    STABLE,
    ChamberData,
    describe_frames,
    fpa_condition,
    setpoints_of,
    stability_mask,
)

__all__ = ["ProtocolCheck", "ProtocolNeeds", "check_protocol", "fpa_plateaus", "record_hint"]

#: Least share of the usable frames in which the FPA rises, and in which it falls, for the FPA
#: to count as moving both ways.
BOTH_WAYS_FRACTION = 0.05
#: Stable frames more than this apart in FPA temperature belong to different plateaus, °C.
PLATEAU_GAP_C = 1.0
#: Fewest stable frames that make a plateau.
PLATEAU_FRAMES = 3


@dataclass(frozen=True)
class ProtocolNeeds:
    """What a chamber session must hold for one method's fit.

    Attributes
    ----------
    frames : {"reference", "stable", "settled", "all"}
        The frames the fit uses: ``"reference"``, the settled frames within ``window_c`` of the
        reference FPA temperature (option ``fpa_ref_c``, default the first usable frame's);
        otherwise a :func:`~thermocal.calibration.dataset.stability_mask` selection (the
        method's option ``frames`` when it takes one).
    setpoints : int
        Distinct blackbody set points those frames must cover.
    fpa_span_c : float
        FPA span those frames must cover, °C.
    fpa_levels : int
        Distinct, well-spread FPA temperatures those frames must hold (the degree of the
        method's polynomial in the FPA temperature + 1).
    window_c : float
        ``"reference"``: how far from the reference FPA temperature the frames may be, °C.
    window_option : str
        The method's option that sets ``window_c``.
    fallback : tuple of str
        Frame selections (the option ``frames``) to fall back to, in order, when the default's
        frames lack what is needed and the option is not given; the fit warns.
    fpa_both_ways : bool
        The FPA must rise and fall, or step between >= 3 plateaus, so that its rate varies
        apart from its temperature (a model of the FPA's dynamics, wolf2016's
        Hammerstein–Wiener estimator, cannot be identified on a ramp).
    rate_term : bool
        The model has an FPA-rate term: without frames taken while the FPA changes, it is
        left out (a warning).
    setpoints_option : tuple (str, int), optional
        An option that, when given, lowers ``setpoints`` (one-point's ``gain``: 1 set point).
    """

    frames: str
    setpoints: int
    fpa_span_c: float = 0.0
    fpa_levels: int = 1
    window_c: float = 0.5
    window_option: str = "fpa_tolerance_c"
    fallback: tuple[str, ...] = ()
    fpa_both_ways: bool = False
    rate_term: bool = False
    setpoints_option: tuple[str, int] | None = None


@dataclass(frozen=True)
class ProtocolCheck:
    """A session checked against a method's needs (:func:`check_protocol`).

    Attributes
    ----------
    method : str
    options : dict
        The options to fit with: those given, and a fallback frame selection.
    refusal : str or None
        Why the session cannot support the method, and what to record (one line); None when it
        can.
    warnings : list of str
        What makes the fit degraded but usable.
    """

    method: str
    options: dict[str, Any]
    refusal: str | None = None
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.refusal is None


def fpa_plateaus(data: ChamberData) -> np.ndarray:
    """The FPA temperatures at which the session holds the FPA still, °C (sorted): the mean of
    each cluster of at least :data:`PLATEAU_FRAMES` stable usable frames, clusters more than
    :data:`PLATEAU_GAP_C` apart."""
    fpa = np.sort(data.fpa_c[data.usable & (data.stability == STABLE)])
    if fpa.size == 0:
        return fpa
    cut = np.flatnonzero(np.diff(fpa) > PLATEAU_GAP_C) + 1
    return np.array([c.mean() for c in np.split(fpa, cut) if c.size >= PLATEAU_FRAMES])


def _simulated_plan(data: ChamberData) -> dict[str, Any] | None:
    """The plan of a session made by ``thermocal simulate chamber`` (None for another)."""
    attrs = data.session.attrs
    if attrs.get("source") != "thermocal simulate chamber":
        return None
    try:
        plan = ast.literal_eval(str(attrs.get("plan", "")))
    except (ValueError, SyntaxError, MemoryError, RecursionError):
        return {}
    return plan if isinstance(plan, dict) else {}


def _range_arg(values: np.ndarray, *, falling: bool = False) -> str:
    """``A:B:STEP`` for evenly spaced values (``A:B:STEP`` of ``--blackbody-c``; ``falling``:
    from the highest down, as a session that swept them so visited them), else ``""``."""
    v = np.unique(np.round(np.asarray(values, dtype=np.float64), 6))
    if v.size < 2:
        return f"{v[0]:g}:{v[0]:g}:1" if v.size else ""
    step = np.diff(v)
    if np.ptp(step) > 1e-6:
        return ""
    a, b = (v[-1], v[0]) if falling else (v[0], v[-1])
    return f"{a:g}:{b:g}:{step[0]:g}"


def _swept_down(blackbody_c: Any) -> bool:
    """Whether a session visited its first two set points from the higher down (a falling
    sweep, ``--blackbody-c 70:10:10``)."""
    values, first = np.unique(np.round(np.asarray(blackbody_c, dtype=np.float64), 6),
                              return_index=True)
    order = values[np.argsort(first)]
    return bool(order.size > 1 and order[0] > order[1])


def _camera_args(data: ChamberData) -> list[str]:
    """The simulated session's camera as ``thermocal simulate chamber`` options (its family,
    unit and size, so that the command records the same camera; those the file states)."""
    attrs = data.session.attrs
    preset, unit = attrs.get("preset"), attrs.get("unit")
    h, w = data.frame_shape
    args = [f"--preset {preset}"] if isinstance(preset, str) and preset.isidentifier() else []
    if isinstance(unit, int | np.integer) and not isinstance(unit, bool) and unit >= 0:
        args.append(f"--unit {int(unit)}")
    return [*args, f"--size {w}x{h}"]


def record_hint(data: ChamberData, profile: str, *, setpoints: int = 0,
                reach_fpa_c: float | None = None) -> str:
    """What to record, in one clause: a ``thermocal simulate chamber`` command for a simulated
    session, words for a real one.

    ``profile`` is the ambient profile that gives what is missing (``"steps"``: plateaus of the
    FPA; ``"sawtooth"``: the FPA rising and falling); ``setpoints`` (when > 0), the set points
    to visit at each; ``reach_fpa_c`` (°C), an FPA temperature the session must reach (a
    reference beyond its FPA range: the ambient range widened by as much, and 2 °C more).
    """
    plan = _simulated_plan(data)
    if plan is not None:
        ambient = plan.get("ambient_c")
        if not (isinstance(ambient, list | tuple) and len(ambient) == 2):
            amb = data.session.ambient_c
            ambient = (float(np.min(amb)), float(np.max(amb))) if amb is not None else (10, 40)
        # at least the default 10…40 °C: the session's own range may be what was too narrow
        ambient = (min(float(ambient[0]), 10.0), max(float(ambient[1]), 40.0))
        if reach_fpa_c is not None and np.isfinite(reach_fpa_c):  # beyond the FPA's range:
            # the FPA follows the ambient, so widen that by as much (a review: the same
            # session's sawtooth never reached a reference 2 °C above it, refused again)
            fpa = data.fpa_c[data.usable] if data.usable.any() else data.fpa_c
            lo, hi = float(fpa.min()), float(fpa.max())
            if reach_fpa_c < lo:
                ambient = (ambient[0] - math.ceil(lo - reach_fpa_c + 2.0), ambient[1])
            elif reach_fpa_c > hi:
                ambient = (ambient[0], ambient[1] + math.ceil(reach_fpa_c - hi + 2.0))
        points = data.setpoints_c
        if setpoints and points.size < setpoints:
            lo = float(points.min()) if points.size else 10.0
            hi = max(float(points.max()) if points.size else 70.0, 70.0)
            # whole-degree steps: a step written to 6 digits (50/3 as 16.6667) could end past
            # the range and lose its last point (the command given gave 3 points of 4)
            points = lo + max(np.floor((hi - lo) / (setpoints - 1)), 1.0) * np.arange(setpoints)
        blackbody = _range_arg(points, falling=_swept_down(data.session.blackbody_c))
        args = [*_camera_args(data), f"--ambient-profile {profile}",
                f"--ambient-c {ambient[0]:g}:{ambient[1]:g}"]
        if blackbody:
            args.append(f"--blackbody-c {blackbody}")
        return f"record {profile}: `thermocal simulate chamber OUT.h5 {' '.join(args)}`"
    visit = f", visiting >= {setpoints} blackbody set points at each" if setpoints else ""
    reach = (f", the FPA reaching {reach_fpa_c:.1f} °C" if reach_fpa_c is not None
             and not float(np.min(data.fpa_c)) <= reach_fpa_c <= float(np.max(data.fpa_c))
             else "")
    if profile == "sawtooth":
        return ("record the chamber's ambient rising and falling across the FPA range (a "
                f"sawtooth{reach}), or stepping between >= 3 plateaus{visit}")
    return ("record the chamber's ambient in steps across the FPA range, each held until the FPA "
            f"settles (within ±0.05 °C/min){visit}")


def _reference(data: ChamberData, options: dict[str, Any]) -> float:
    ref = options.get("fpa_ref_c")
    if ref is not None:
        return float(ref)
    usable = np.flatnonzero(data.usable)
    return float(data.fpa_c[usable[0]]) if usable.size else float("nan")


def _lacks(data: ChamberData, sel: np.ndarray, needs: ProtocolNeeds, n_setpoints: int,
           what: str) -> str | None:
    """What the frames ``sel`` lack of ``needs`` (a clause), or None."""
    points = setpoints_of(data, sel)
    if points.size < n_setpoints:
        total = data.setpoints_c.size
        of = f" of the session's {total}" if total > points.size else ""
        listed = f" ({', '.join(f'{v:g}' for v in points)} °C)" if points.size else ""
        return (f"needs >= {n_setpoints} blackbody set points in {what}, which give "
                f"{points.size or 'none'}{of}{listed}")
    fpa = data.fpa_c[data.usable & sel]
    span = float(np.ptp(fpa)) if fpa.size else 0.0
    whole = float(np.ptp(data.fpa_c[data.usable]))
    total = f" of the session's {whole:.2f} °C" if whole > span + 0.5 else ""
    if span < needs.fpa_span_c:
        return (f"needs FPA temperatures spanning >= {needs.fpa_span_c:g} °C in {what}, which "
                f"span {span:.2f} °C{total}")
    if needs.fpa_levels > 1 and fpa_condition(fpa, needs.fpa_levels - 1) > MAX_FPA_CONDITION:
        return (f"needs the FPA at >= {needs.fpa_levels} well-spread temperatures in {what}, "
                f"which hold it at fewer ({fpa.min():.2f}…{fpa.max():.2f} °C{total})")
    return None


def check_protocol(data: ChamberData, method: str, needs: ProtocolNeeds,
                   **options: Any) -> ProtocolCheck:
    """Check that a prepared chamber session holds what calibration ``method`` needs.

    Parameters
    ----------
    data : ChamberData
        The prepared session (:func:`~thermocal.calibration.dataset.prepare_chamber`).
    method : str
        The method's name, for the messages.
    needs : ProtocolNeeds
        What it needs (its registry entry's: see
        :func:`~thermocal.calibration.registry.check_session`).
    **options
        The method's fitting options (``fpa_ref_c``, ``frames``, the window, ...).

    Returns
    -------
    ProtocolCheck
        Its ``refusal`` names what the session lacks and what to record; a fallback frame
        selection is in its ``options``, with a warning.
    """
    n_setpoints = needs.setpoints
    if needs.setpoints_option and options.get(needs.setpoints_option[0]) is not None:
        n_setpoints = needs.setpoints_option[1]
    warnings: list[str] = []
    options = dict(options)
    if not data.usable.any():
        return ProtocolCheck(method, options, f"{method}: the session has no usable frame")
    if needs.frames == "reference":
        ref = _reference(data, options)
        window = float(options.get(needs.window_option, needs.window_c))
        frames = str(options.get("frames", "settled"))
        sel = stability_mask(data, frames) & (np.abs(data.fpa_c - ref) <= window)
        what = f"{describe_frames(data, frames)} within ±{window:g} °C of the reference FPA " \
               f"{ref:.2f} °C"
        lack = _lacks(data, sel, needs, n_setpoints, what)
        if lack:
            plateaus = fpa_plateaus(data)
            elsewhere = ("; or choose fpa_ref_c (--fpa-ref-c) at one of its FPA plateaus ("
                         + ", ".join(f"{p:.1f}" for p in plateaus[:8]) + " °C)"
                         if plateaus.size else "")
            # the FPA moving slowly through the reference: steps of a few °C leave one plateau
            # within the window (the boson preset's default steps session, refused again)
            return ProtocolCheck(method, options, f"{method} {lack}; "
                                 + record_hint(data, "sawtooth", setpoints=n_setpoints,
                                               reach_fpa_c=ref)
                                 + elsewhere)
    else:
        given = "frames" in options
        choices = ((str(options["frames"]),) if given else (needs.frames, *needs.fallback))
        first_lack = None
        for frames in choices:
            what = describe_frames(data, frames)
            lack = _lacks(data, stability_mask(data, frames), needs, n_setpoints, what)
            if lack is None:
                break
            first_lack = first_lack or lack
        if lack is not None:
            hint = record_hint(data, "steps", setpoints=n_setpoints)
            also = "" if given or not needs.fallback else "; nor do " + " or ".join(
                "all the frames" if f == "all" else describe_frames(data, f)
                for f in needs.fallback)
            other = (f"; or fit frames='{needs.fallback[0]}'"
                     if given and needs.fallback and options["frames"] == needs.frames else "")
            return ProtocolCheck(method, options, f"{method} {first_lack}{also}; {hint}{other}")
        if frames != choices[0]:
            options["frames"] = frames
            warnings.append(
                f"{method} {first_lack}: fitted to {describe_frames(data, frames)} instead; its "
                "model has no FPA-rate term, so a changing FPA biases it (see the expected "
                f"error); for a fit to stable frames, {record_hint(data, 'steps')}"
            )
    if needs.fpa_both_ways:
        rate = data.fpa_rate_c_per_min[data.usable]
        stable = float(data.info.get("stable_c_per_min", 0.05))
        rises = float(np.mean(rate > stable))
        falls = float(np.mean(rate < -stable))
        plateaus = fpa_plateaus(data)
        if min(rises, falls) < BOTH_WAYS_FRACTION and plateaus.size < 3:
            way = ("barely changes" if max(rises, falls) < BOTH_WAYS_FRACTION
                   else "only rises" if rises >= falls else "only falls")
            held = (f"holds still only at {', '.join(f'{p:.1f}' for p in plateaus)} °C"
                    if plateaus.size else "never holds still")
            return ProtocolCheck(
                method, options,
                f"{method} needs the FPA to rise and fall, or to step between >= 3 plateaus, to "
                f"tell its rate from its temperature (its Hammerstein-Wiener estimator); this "
                f"session's FPA {way} ({rate.min():+.2f}…{rate.max():+.2f} °C/min) and "
                f"{held}; {record_hint(data, 'sawtooth')}, or steps",
            )
    if needs.rate_term:
        moving = data.usable & (data.stability != STABLE)
        rate = data.fpa_rate_c_per_min[data.usable]
        if moving.sum() < 3 or float(np.ptp(rate)) <= 0.1:
            warnings.append(
                f"{method}: no frames with a changing FPA, so its FPA-rate correction (Lin et "
                "al. eq. 2) is left out; record while the chamber's ambient changes too"
            )
    return ProtocolCheck(method, options, None, warnings)
