"""Accumulator: the run's answer from independent passes (mean, batch-means error, drift).

Every pass of an integrator is a complete, independent estimate Ê_i (see
`/work/shared/reference/bidirectional-estimator.md`). The run's answer is the plain
mean of the passes and its standard error is the sample standard deviation of the
Ê_i over √n — per pixel and for the total flux. The state is nothing but sums
(n, Σ Ê_i, Σ Ê_i²) plus the per-pass totals, so it is also the checkpoint: merging
passes in pass order gives bit-identical numbers on one worker or many.

The progressive radius still shrinks from pass to pass, so the mean of Ê_i drifts
(the density-estimation bias). `drift()` compares the first half of the passes with
the second half; a drift well beyond its own error bar says "run more passes".
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from lensmount.atomic import write_npz
from lensmount.integrators.estimate import PassEstimate

_STATE_VERSION = 4  # 2: elapsed time; 3: energy ledger; 4: diagnostics


@dataclass
class Drift:
    """First-half vs second-half means of the total flux.

    relative : (second − first) / overall mean (0 when the mean is 0)
    z : the difference over its own standard error (0 when that is 0 or n < 4)
    p : two-sided p-value of Welch's t-test on the two halves (1 when undefined). With
        few passes z is far from normal (|z| > 2 happens 17 % of the time at n = 4),
        so judge significance by p, not by z.
    """

    relative: float
    z: float
    p: float = 1.0


@dataclass
class Accumulator:
    """Sums over passes. Build with `Accumulator.empty(shape, part_names, pixel_area_mm2)`.

    n : passes added
    sum_image, sumsq_image : (ny, nx) Σ Ê_i and Σ Ê_i² (normalised irradiance E/E_sun)
    sum_parts : (P, ny, nx) Σ of the per-part images
    pass_flux : list of each pass's total flux (mm², normalised), in pass order
    pass_part_flux : list of each pass's (P,) per-part flux
    photons, lost_flux : totals over the passes
    ledger : Σ over the passes of each energy-ledger entry (mm², `PassEstimate.ledger`)
    diagnostics : Σ over the passes of each count in `PassEstimate.diagnostics`
    last_pass : index of the last pass added (-1 before any)
    elapsed_s : wall time spent on the passes, summed over resumed parts of a run
    """

    part_names: list[str]
    pixel_area_mm2: float
    sum_image: np.ndarray
    sumsq_image: np.ndarray
    sum_parts: np.ndarray
    n: int = 0
    photons: int = 0
    lost_flux: float = 0.0
    last_pass: int = -1
    elapsed_s: float = 0.0
    pass_flux: list[float] = field(default_factory=list)
    pass_part_flux: list[np.ndarray] = field(default_factory=list)
    ledger: dict[str, float] = field(default_factory=dict)
    diagnostics: dict[str, float] = field(default_factory=dict)

    @classmethod
    def empty(cls, shape: tuple[int, int], part_names: list[str], pixel_area_mm2: float) -> "Accumulator":
        ny, nx = shape
        return cls(list(part_names), float(pixel_area_mm2), np.zeros((ny, nx)), np.zeros((ny, nx)),
                   np.zeros((len(part_names), ny, nx)))

    # -- adding passes -------------------------------------------------------------------

    def add(self, estimate: PassEstimate, pass_index: int | None = None) -> None:
        """Add one pass. Non-finite pixels are a bug upstream; they are refused, not hidden."""
        image = np.asarray(estimate.image, dtype=np.float64)
        parts = np.asarray(estimate.per_part, dtype=np.float64)
        if image.shape != self.sum_image.shape:
            raise ValueError(f"pass image {image.shape} != accumulator {self.sum_image.shape}")
        if list(estimate.part_names) != self.part_names:
            raise ValueError("pass part names differ from the accumulator's")
        if not (np.isfinite(image).all() and np.isfinite(parts).all()):
            raise ValueError("pass estimate contains NaN or Inf")
        self.sum_image += image
        self.sumsq_image += image * image
        self.sum_parts += parts
        self.n += 1
        self.photons += int(estimate.photons)
        self.lost_flux += float(estimate.lost_flux)
        for key, value in estimate.ledger.items():
            if not np.isfinite(value):
                raise ValueError(f"pass energy ledger entry '{key}' is not finite")
            self.ledger[key] = self.ledger.get(key, 0.0) + float(value)
        for key, value in estimate.diagnostics.items():
            self.diagnostics[key] = self.diagnostics.get(key, 0.0) + float(value)
        self.pass_flux.append(float(image.sum() * self.pixel_area_mm2))
        self.pass_part_flux.append(parts.sum(axis=(1, 2)) * self.pixel_area_mm2)
        self.last_pass = self.last_pass + 1 if pass_index is None else int(pass_index)

    # -- the answer ------------------------------------------------------------------------

    @property
    def mean_image(self) -> np.ndarray:
        """(ny, nx) mean normalised irradiance E/E_sun (zeros before any pass)."""
        return self.sum_image / max(self.n, 1)

    @property
    def mean_parts(self) -> np.ndarray:
        """(P, ny, nx) mean per-part normalised irradiance."""
        return self.sum_parts / max(self.n, 1)

    @property
    def std_error_image(self) -> np.ndarray:
        """(ny, nx) standard error per pixel from the spread of the passes (zeros for n < 2)."""
        if self.n < 2:
            return np.zeros_like(self.sum_image)
        mean = self.sum_image / self.n
        var = np.maximum(self.sumsq_image / self.n - mean * mean, 0.0) * self.n / (self.n - 1)
        return np.sqrt(var / self.n)

    @property
    def flux(self) -> float:
        """Mean detector stray flux normalised by E_sun (mm²)."""
        return float(np.mean(self.pass_flux)) if self.n else 0.0

    @property
    def flux_std_error(self) -> float:
        """Standard error of `flux` (batch means over passes); inf for n < 2 (unknown)."""
        return _std_error(np.asarray(self.pass_flux))

    @property
    def part_flux(self) -> np.ndarray:
        """(P,) mean flux per part (mm²)."""
        if not self.n:
            return np.zeros(len(self.part_names))
        return np.mean(np.asarray(self.pass_part_flux), axis=0)

    @property
    def part_flux_std_error(self) -> np.ndarray:
        """(P,) standard error of the per-part flux; inf for n < 2."""
        if self.n < 2:
            return np.full(len(self.part_names), math.inf)
        series = np.asarray(self.pass_part_flux)
        return np.array([_std_error(series[:, p]) for p in range(series.shape[1])])

    def rel_error(self) -> float:
        """Relative standard error of the total flux, for the stopping rule.

        inf when unknown (n < 2, or a zero mean with spread); 0 when every pass gave
        exactly zero (nothing reaches the detector: more passes cannot change that).
        """
        if self.n < 2:
            return math.inf
        se, mean = self.flux_std_error, abs(self.flux)
        if mean > 0:
            return se / mean
        return 0.0 if se == 0 else math.inf

    def drift(self) -> Drift:
        """First-half vs second-half means of the total flux (the radius bias indicator)."""
        f = np.asarray(self.pass_flux)
        if len(f) < 4:
            return Drift(0.0, 0.0, 1.0)
        h = len(f) // 2
        a, b = f[:h], f[h:]
        diff = float(b.mean() - a.mean())
        mean = float(f.mean())
        rel = diff / mean if mean != 0 else 0.0
        se = math.hypot(_std_error(a), _std_error(b))
        z = diff / se if se > 0 and math.isfinite(se) else 0.0
        p = 1.0
        if se > 0 and math.isfinite(se):
            from scipy.stats import ttest_ind

            p = float(ttest_ind(b, a, equal_var=False).pvalue)
            p = p if math.isfinite(p) else 1.0
        return Drift(rel, z, p)

    @property
    def mean_ledger(self) -> dict[str, float]:
        """The energy ledger per pass (mean over the passes), mm²."""
        return {k: v / max(self.n, 1) for k, v in sorted(self.ledger.items())}

    # -- checkpoint ------------------------------------------------------------------------

    def save(self, path: str | os.PathLike, **meta) -> None:
        """Write the state to an .npz atomically; `meta` (seed, input_hash, method, ...) goes along."""
        path = Path(path)
        arrays = dict(
            version=np.int64(_STATE_VERSION), n=np.int64(self.n), photons=np.int64(self.photons),
            lost_flux=np.float64(self.lost_flux), last_pass=np.int64(self.last_pass),
            elapsed_s=np.float64(self.elapsed_s),
            pixel_area_mm2=np.float64(self.pixel_area_mm2), part_names=np.array(self.part_names, dtype=str),
            sum_image=self.sum_image, sumsq_image=self.sumsq_image, sum_parts=self.sum_parts,
            pass_flux=np.asarray(self.pass_flux, dtype=np.float64),
            pass_part_flux=np.asarray(self.pass_part_flux, dtype=np.float64).reshape(-1, len(self.part_names)),
            ledger_keys=np.array(sorted(self.ledger), dtype=str),
            ledger_values=np.array([self.ledger[k] for k in sorted(self.ledger)], dtype=np.float64),
            diagnostics_keys=np.array(sorted(self.diagnostics), dtype=str),
            diagnostics_values=np.array([self.diagnostics[k] for k in sorted(self.diagnostics)], dtype=np.float64),
        )
        for key, value in meta.items():
            arrays[f"meta_{key}"] = np.array(value)
        write_npz(path, compressed=True, **arrays)  # stray-light images are mostly zeros: ~20x smaller

    @classmethod
    def load(cls, path: str | os.PathLike) -> tuple["Accumulator", dict]:
        """The state and its meta dict (values as Python scalars/strings)."""
        with np.load(path, allow_pickle=False) as z:
            if int(z["version"]) != _STATE_VERSION:
                raise ValueError(f"checkpoint version {int(z['version'])} is not {_STATE_VERSION}")
            names = [str(s) for s in z["part_names"]]
            acc = cls(names, float(z["pixel_area_mm2"]), z["sum_image"].copy(), z["sumsq_image"].copy(),
                      z["sum_parts"].copy(), n=int(z["n"]), photons=int(z["photons"]),
                      lost_flux=float(z["lost_flux"]), last_pass=int(z["last_pass"]),
                      elapsed_s=float(z["elapsed_s"]),
                      pass_flux=[float(v) for v in z["pass_flux"]],
                      pass_part_flux=[row.copy() for row in z["pass_part_flux"]],
                      ledger={str(k): float(v) for k, v in zip(z["ledger_keys"], z["ledger_values"])},
                      diagnostics={str(k): float(v) for k, v in zip(z["diagnostics_keys"], z["diagnostics_values"])})
            meta = {k[5:]: z[k].item() for k in z.files if k.startswith("meta_")}
        return acc, meta


def _std_error(series: np.ndarray) -> float:
    """Sample standard deviation / √n of a 1-D series; inf for fewer than 2 values."""
    n = len(series)
    if n < 2:
        return math.inf
    return float(np.std(series, ddof=1) / math.sqrt(n))


__all__ = ["Accumulator", "Drift"]
