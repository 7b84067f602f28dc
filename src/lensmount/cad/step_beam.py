"""A foreign part against the designed beam: its clearance to the envelope and the vignetting it causes.

The clearance is measured on the part's mesh vertices against the real-ray envelope
(`Layout.envelope.exact`: every field 0…max, full pupil, every wavelength), where the part lies
within the beam's z range. A vertex check cannot see a flat face spanning the beam between
vertices, so the vignetting is measured as well: each listed field's full pupil (a square grid of
PUPIL_GRID points across, so every ray stands for the same pupil area; primary wavelength, real-ray
aiming), turned to AZIMUTHS azimuths about the axis (a STEP part need not be
a solid of revolution), followed through the lens to the image plane; the fraction of the rays that
reach it through the lens but meet the part on the way (Embree, `cad.pupil.MountHits`) is that
field's vignetting.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.cad.pupil import MountHits
from lensmount.mesh import TaggedMesh
from lensmount.optics.realrays import aim, trace

AZIMUTHS = 8
PUPIL_GRID = 25  # ~490 rays a field: a vignetted fraction to about ±2 %


@dataclass
class BeamReport:
    """clearance: smallest radial distance (mm) of the part outside the envelope (negative: inside),
    at (r, z); fields (F,) as the lens file lists them (deg or mm); vignetting (F,) mean fraction over
    azimuths; worst (F,) the largest at one azimuth; worst_azimuth_deg (F,) that azimuth: the direction
    of the field's image point from +x towards +y."""

    clearance: float
    at: tuple[float, float]
    fields: np.ndarray
    vignetting: np.ndarray
    worst: np.ndarray
    worst_azimuth_deg: np.ndarray

    def lines(self, unit: str) -> str:
        def worst(f, v, w, a) -> str:
            if w <= v + 1e-9:
                return ""
            return f" (up to {100 * w:.2f} % at " + (f"azimuth {round(a) % 360}°)" if f != 0 else "one azimuth)")

        return ", ".join(f"field {f:g}{unit}: {100 * v:.2f} %{worst(f, v, w, a)}"
                         for f, v, w, a in zip(self.fields, self.vignetting, self.worst, self.worst_azimuth_deg))


def beam_clearance(layout, mesh: TaggedMesh) -> tuple[float, tuple[float, float]]:
    """Smallest r − envelope(z) over the part's vertices inside the beam's z range, and where."""
    env = layout.envelope
    v = mesh.vertices
    r, z = np.hypot(v[:, 0], v[:, 1]), v[:, 2]
    inside = (z >= env.z[0]) & (z <= env.z[-1])
    if not inside.any():
        return float("inf"), (float("nan"), float("nan"))
    gap = r[inside] - env.at(z[inside])
    near = np.flatnonzero(gap < gap.min() + 1.0)  # the exact envelope only where it decides
    exact = r[inside][near] - env.exact(z[inside][near])
    k = int(np.argmin(exact))
    return float(exact[k]), (float(r[inside][near][k]), float(z[inside][near][k]))


def vignetting(layout, mesh: TaggedMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(fields, mean vignetting per field, the worst azimuth's, that azimuth in degrees) caused by the part
    `mesh`. The azimuth is where the field's image point lies, from +x towards +y (0 on axis)."""
    p = layout.prescription
    fields = np.unique(np.concatenate([[0.0], np.abs(np.asarray(p.field_values, dtype=np.float64))]))
    wl = p.primary_wavelength_um
    o, d = aim(p, fields, pupil_grid(PUPIL_GRID), wl)
    rays = trace(p, o, d, wl, clip=True)
    z_start = min(float(mesh.vertices[:, 2].min()) - 1.0, float(o[:, 2].min()))
    start = o - d * ((o[:, 2] - z_start) / d[:, 2])[:, None]
    path = np.concatenate([start[None], rays.points], axis=0)  # (S+2, N, 3)
    arrived = ~rays.vignetted
    hits = MountHits(mesh)
    per = len(o) // len(fields)
    lost = np.zeros((AZIMUTHS, len(fields)))
    azimuth = np.zeros((AZIMUTHS, len(fields)))
    for a in range(AZIMUTHS):
        c, s = np.cos(2 * np.pi * a / AZIMUTHS), np.sin(2 * np.pi * a / AZIMUTHS)
        turned = path.copy()
        turned[..., 0], turned[..., 1] = c * path[..., 0] - s * path[..., 1], s * path[..., 0] + c * path[..., 1]
        blocked = np.zeros(len(o), bool)
        for seg_a, seg_b in zip(turned[:-1], turned[1:]):
            todo = arrived & ~blocked
            if todo.any():
                blocked[todo] = hits.first(seg_a[todo], seg_b[todo]) >= 0
        for f in range(len(fields)):
            sl = slice(f * per, (f + 1) * per)
            n = int(arrived[sl].sum())
            lost[a, f] = blocked[sl].sum() / n if n else 0.0
            if n and fields[f] != 0:
                x, y = turned[-1, sl][arrived[sl]].mean(axis=0)[:2]
                azimuth[a, f] = np.degrees(np.arctan2(y, x)) % 360.0
    # several azimuths may lose the most alike (a wall across a whole side): their circular mean
    tied = lost >= lost.max(axis=0) - 1e-9
    angle = np.radians(azimuth)
    worst = np.degrees(np.arctan2((np.sin(angle) * tied).sum(axis=0), (np.cos(angle) * tied).sum(axis=0))) % 360.0
    return fields, lost.mean(axis=0), lost.max(axis=0), np.where(fields != 0, worst, 0.0)


def pupil_grid(n: int) -> np.ndarray:
    """(P, 2) normalised pupil points on a square grid inside the unit disc (equal area each)."""
    u = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(u, u)
    inside = x ** 2 + y ** 2 <= 1.0
    return np.column_stack([x[inside], y[inside]])


def beam_report(layout, mesh: TaggedMesh) -> BeamReport:
    clearance, at = beam_clearance(layout, mesh)
    fields, mean, worst, azimuth = vignetting(layout, mesh)
    return BeamReport(clearance, at, fields, mean, worst, azimuth)


__all__ = ["BeamReport", "beam_clearance", "vignetting", "beam_report", "pupil_grid"]
