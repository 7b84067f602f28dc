"""The estimator's knobs in one frozen record: what the runner sends to workers, what
`summary.json` records as `estimator_settings` and what goes into the input hash.

A run is reproduced by (method, seed, photons per pass, these settings, the inputs).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

from lensmount.errors import InputError


@dataclass(frozen=True)
class EstimatorSettings:
    """Knobs of the photon walk (both methods) and of the gather (bidirectional).

    Args:
        max_bounces: scattering events per photon; flux still travelling after them is `lost/bounce_limit`.
        roulette_after: scattering events before Russian roulette starts.
        roulette_level: roulette keeps a photon with q = min(1, Φ / (roulette_level · Φ0)), Φ0 its emitted flux.
        alpha: progressive radius shrink, 0 < alpha < 1 (radius scale s_i of pass i).
        samples_per_pixel: backward samples per pixel per pass (view map).
        view_map_pitch: the view map samples blocks of this many × this many pixels, `samples_per_pixel`
            a block a pass, each standing for its block (`view_map`): k² fewer backward rays a pass for the
            same expected image and total; the image needs about k² more passes to fill in.
        mixture_c: share of backward directions aimed at the exit targets (the rest cosine-weighted).
        glossy_threshold_deg: lobes narrower than this half width are followed by photons, not gathered...
        gathered_share: ...unless this share of their albedo lies beyond sin(glossy_threshold_deg) of the
            mirror direction (direction cosines): then that part is gathered and the core followed.
        normal_limit_deg: a photon is gathered only where its face normal is within this of the hit point's.
        neighbours: the k-th nearest hit point on the same face sets the initial radius r_0.
        radius_cap_mm: upper bound of r_0 (mm), before the per-face strip limit.
        ghost_routes: with ghosts on, the `ghosts` channel's two- (and four-) reflection light comes
            from deterministic ghost routes (`integrators.ghost_routes`), not from photons.
        ghost_rays_across: lattice points per pass across the first surface for those routes.
        edge_photons: bidirectional with a broad `diaphragm-edge` face and the sun (or a collimated
            source): most photons start where a pilot found they meet the edge
            (`integrators.photon_mapping.photon_target`), weighted by the mixture density (unbiased either way).
        connect_direct_view: bidirectional: light whose last segment runs straight from a broad face to
            the detector is counted by connecting each photon there to a point of the detector
            (`integrators.photon_mapping.connect`), not by the gather (unbiased either way; no kernel bias there).
        connect_through_optics: bidirectional, with connect_direct_view: each broad scatter in front of the
            optics is also connected through them to a point of a face the detector sees straight
            (`integrators.photon_mapping.refracted_connection`), combined with the photons' own way there by the balance heuristic.
            Off by default: on the reference design it costs 3–5× a pass and narrows the passes' spread only
            at 45° (docs/bidirectional.md, "Connection through the optics").
    """

    max_bounces: int = 64
    roulette_after: int = 3
    roulette_level: float = 1e-3
    alpha: float = 0.7
    samples_per_pixel: int = 1
    view_map_pitch: int = 1
    mixture_c: float = 0.5
    glossy_threshold_deg: float = 15.0
    gathered_share: float = 0.25
    normal_limit_deg: float = 30.0
    neighbours: int = 8
    radius_cap_mm: float = 5.0
    ghost_routes: bool = True
    ghost_rays_across: int = 33
    edge_photons: bool = True
    connect_direct_view: bool = True
    connect_through_optics: bool = False

    def __post_init__(self):
        checks = {
            "max_bounces": (self.max_bounces >= 0, "an integer >= 0"),
            "roulette_after": (self.roulette_after >= 0, "an integer >= 0"),
            "roulette_level": (0.0 < self.roulette_level <= 1.0, "0 < roulette_level <= 1"),
            "alpha": (0.0 < self.alpha < 1.0, "0 < alpha < 1"),
            "samples_per_pixel": (self.samples_per_pixel >= 1, "an integer >= 1"),
            "view_map_pitch": (self.view_map_pitch >= 1, "an integer >= 1 (pixels)"),
            "mixture_c": (0.0 <= self.mixture_c <= 1.0, "0 <= mixture_c <= 1"),
            "glossy_threshold_deg": (0.0 <= self.glossy_threshold_deg <= 90.0, "0 to 90 degrees"),
            "gathered_share": (0.0 < self.gathered_share <= 1.0, "0 < gathered_share <= 1"),
            "normal_limit_deg": (0.0 < self.normal_limit_deg <= 90.0, "0 < normal_limit_deg <= 90"),
            "neighbours": (self.neighbours >= 1, "an integer >= 1"),
            "radius_cap_mm": (0.0 < self.radius_cap_mm < math.inf, "a positive length in mm"),
            "ghost_rays_across": (self.ghost_rays_across >= 3, "an integer >= 3"),
        }
        for name, (ok, valid) in checks.items():
            if not ok:
                raise InputError(f"estimator setting {name} = {getattr(self, name)!r} is out of range",
                                 field=name, valid=valid)

    def as_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, values: dict) -> "EstimatorSettings":
        """From a dict (a summary's `estimator_settings`); unknown keys are errors."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise InputError(f"unknown estimator setting '{unknown[0]}'", field=unknown[0],
                             valid=", ".join(sorted(known)))
        return cls(**values)


__all__ = ["EstimatorSettings"]
