"""summary.json content from an Accumulator: the numbers a user reads first.

Every value is finite or null (unknown, e.g. an error bar from a single pass); the
writer refuses NaN/Inf, so this module guards each division itself.
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.analysis.bias import BiasBound
from lensmount.analysis.metrics import finite_or_none, stray_fraction
from lensmount.analysis.passes import LIGHT_TAIL, TAIL_P, UNBOUNDED_TAIL, Accumulator
from lensmount.analysis.paths import describe_event
from lensmount.integrators.paths import EMPTY
from lensmount.integrators.estimate import TIME_PREFIX, ledger_residual


def build_summary(acc: Accumulator, *, method: str, seed: int, effects_ran: list[str], effects_skipped: list[str],
                  time_s: float, aperture_flux_mm2: float, input_hash: str, estimator_settings: dict,
                  extra: dict | None = None, tag_table=None) -> dict:
    """The summary dict. aperture_flux_mm2: flux entering the entrance pupil per unit E_sun;
    estimator_settings: `EstimatorSettings.as_dict()` (with method, seed and photons per pass in
    `extra`, what reproduces the run).

    The error bar is `stray_fraction_std_error` (spread of the passes, Student-t widened) plus
    `stray_fraction_bias_bound` (kernel bias, `Accumulator.bias_bound`); `stray_fraction_rel_error`
    is their sum over the value. A bias the ladder of radii cannot bound has no bound (null) and
    `stray_fraction_bias_unbounded` says why (null when bounded; per part `bias_unbounded`): its error is
    unknown, and `compare` and the stopping rule take it so, never as zero. With no signal at all `stray_fraction_upper_bound` is the 95 %
    bound from the photons traced (`Accumulator.upper_bound`) and the relative error is null;
    `stray_fraction_no_signal_bound` is that bound for any figure that read zero (a part too), what
    `compare` takes for a zero instead of 0 ± 0. `tail` says whether one pass dominates the others
    (`tail_block`; tag_table names its path) and how heavy the tail of the terms the passes sum is: its
    allowance (`stray_fraction_tail_allowance`) is part of `stray_fraction_std_error`."""
    flux, se = acc.flux, acc.flux_std_error
    bias, part_bias = acc.bias_bound()
    upper = acc.upper_bound()
    scale = 1.0 / aperture_flux_mm2 if aperture_flux_mm2 > 0 else 0.0
    drift = acc.drift()
    part_flux, part_se = acc.part_flux, acc.part_flux_std_error
    per_part = {
        name: {"fraction": finite_or_none(stray_fraction(float(f), aperture_flux_mm2)),
               "std_error": finite_or_none(float(s) * scale) if np.isfinite(s) else None,
               "bias_bound": _bound(b, scale),
               "bias_unbounded": None if b.bounded else b.reason,
               "flux_mm2": finite_or_none(float(f))}
        for name, f, s, b in zip(acc.part_names, part_flux, part_se, part_bias)
    }
    image = acc.mean_image
    summary = {
        "method": method,
        "seed": int(seed),
        "effects": list(effects_ran),
        "effects_skipped": list(effects_skipped),
        "photons": int(acc.photons),
        "passes": int(acc.n),
        "time_s": round(float(time_s), 3),
        "stray_flux_mm2": finite_or_none(flux),
        "stray_flux_std_error_mm2": finite_or_none(se),
        "aperture_flux_mm2": finite_or_none(aperture_flux_mm2),
        "stray_fraction": finite_or_none(stray_fraction(flux, aperture_flux_mm2)),
        "stray_fraction_std_error": finite_or_none(se * scale),
        "stray_flux_bias_bound_mm2": _bound(bias, 1.0),
        "stray_fraction_bias_bound": _bound(bias, scale),
        "stray_fraction_bias_unbounded": None if bias.bounded else bias.reason,
        "bias": {"outward_step": finite_or_none(bias.step * scale), "shape_p": finite_or_none(bias.shape_p)},
        "stray_fraction_tail_allowance": finite_or_none(acc.tail().allowance * scale),
        "stray_fraction_upper_bound": None if upper is None else finite_or_none(upper * scale),
        "stray_fraction_no_signal_bound": finite_or_none(acc.no_signal_bound() * scale),
        "stray_fraction_rel_error": finite_or_none(acc.rel_error()),
        "stray_fraction_drift": finite_or_none(drift.relative),
        "stray_fraction_drift_z": finite_or_none(drift.z),
        "stray_fraction_drift_p": finite_or_none(drift.p),
        "tail": tail_block(acc, tag_table),
        "mean_irradiance": finite_or_none(float(image.mean()) if image.size else 0.0),
        "peak_irradiance": finite_or_none(float(image.max()) if image.size else 0.0),
        "lost_flux": finite_or_none(acc.lost_flux / max(acc.n, 1)),
        "per_part": per_part,
        "estimator_settings": dict(estimator_settings),
        "energy_ledger": energy_ledger(acc),
        "diagnostics": {k: finite_or_none(v) for k, v in sorted(acc.diagnostics.items())
                        if not k.startswith(TIME_PREFIX)},  # seconds vary run to run: the plan block has them
        "input_hash": input_hash,
        "units": {"irradiance": "E/E_sun", "flux": "mm² (flux / E_sun)"},
    }
    if extra:
        summary.update(extra)
    return summary


def _bound(bias: BiasBound, scale: float) -> float | None:
    """A bias bound in the summary's units: null when unknown (inf) or when there is none (not bounded)."""
    return None if bias.bound is None or not np.isfinite(bias.bound) else finite_or_none(bias.bound * scale)


NOTABLE_ALLOWANCE = 0.1  # a note when the tail allowance is this share of the standard error or more (case 1: 0.01)


def tail_block(acc: Accumulator, tag_table=None) -> dict:
    """The largest pass against the others (`Accumulator.tail`), and when it dominates them
    (`heavy`) a sentence saying so and the path it came from: the error bar is then not the spread's.
    The tail index of the terms the passes sum (`terms_tail_index`, null when unknown or without a tail) and,
    when its allowance is a notable part of the error bar (or it has none), a sentence in `note` saying so."""
    t = acc.tail()
    block = {"largest_pass": t.largest_pass if acc.n else None,
             "largest_over_median": finite_or_none(t.over_median) if t.over_median is not None else None,
             "largest_share": finite_or_none(t.share), "outlier_p": finite_or_none(t.p), "heavy": bool(t.heavy),
             "terms_tail_index": None if t.index is None else finite_or_none(t.index),
             "terms_unbounded": bool(math.isinf(t.allowance)),
             "terms_bound_mm2": finite_or_none(t.bound) if math.isfinite(t.bound) else None}
    notes = []
    path = acc.paths.events.get(t.path, ()) if t.path != EMPTY else ()
    if tag_table is not None and path:
        block["path"] = [describe_event(c, tag_table)["name"] for c in path]
    if t.heavy:
        ratio = f"{t.over_median:.2f}× the median" if t.over_median is not None else "against a median of 0"
        via = f" (its excess came by {' → '.join(block['path'])})" if "path" in block else ""
        notes.append(f"pass {t.largest_pass} dominates the others: {ratio}, {100 * t.share:.1f} % of the sum of "
                     f"{acc.n} passes, p = {t.p:.2g} < {TAIL_P:g} that it belongs with them{via}. The "
                     "passes are heavy-tailed: the standard error from their spread is not to be trusted "
                     "and the run does not count as converged; run more passes.")
    if math.isinf(t.allowance):
        notes.append(f"the largest terms the passes sum fall off as x^-{t.index:.2f} (tail index at most "
                     f"{UNBOUNDED_TAIL:g}): what the run has not met yet has no bound, so it cannot bound its error "
                     "and does not count as converged; more passes help only once they reach the tail's end, "
                     "a sampling that avoids the heavy terms does (the path of the largest pass in `path`).")
    elif t.index is not None and t.allowance > 0 and t.allowance >= NOTABLE_ALLOWANCE * acc.flux_std_error:
        notes.append(f"the largest terms the passes sum fall off as x^-{t.index:.2f} (below {LIGHT_TAIL:g}): "
                     f"a heavy tail; the error bar adds the tail allowance "
                     f"({100 * t.allowance / abs(acc.flux) if acc.flux else 0:.2g} % of the value), what a run "
                     "that has not met its tail yet misses.")
    if notes:
        block["note"] = " ".join(notes)
    return block


def energy_ledger(acc: Accumulator) -> dict:
    """Where the emitted flux went, per pass (mm², flux / E_sun), and how well it balances.

    `entries` holds the named sums (docs/bidirectional.md, "energy ledger"); `residual_rel` is
    (source − Σ others) / source, zero to rounding when every photon is accounted for.
    """
    entries = acc.mean_ledger
    return {"entries": {k: finite_or_none(v) for k, v in entries.items()},
            "residual_rel": finite_or_none(ledger_residual(entries)),
            "units": "mm² (flux / E_sun) per pass"}


__all__ = ["build_summary", "energy_ledger", "tail_block"]
