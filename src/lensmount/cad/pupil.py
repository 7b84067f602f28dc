"""The entrance pupil the mount realises, measured on the mesh with real rays.

On-axis rays of the primary wavelength enter parallel to the axis at height rho and
azimuth phi (from a finite object: leave the axial object point at slope u = tan of their angle to
the axis, toward azimuth phi, as `optics.realrays.axial_rim_ray` does at the rim; the slope, not
the height on the entrance pupil's plane, so a pupil far away or at infinity, as in telecentric
object space, measures the same);
the sequential trace (`optics.realrays`) gives each one's path through
the glass, and every straight piece of that path is tested against the mount's
triangles with Embree (the optical faces excepted: the trace already refracted
there). For each azimuth the largest rho whose ray reaches the image plane without
meeting metal or a lens edge is found by bisection; the realised entrance pupil is
the circle of the same area (from a finite object: the cone of the same solid angle, as its
numerical aperture, and the pupil it cuts on the paraxial entrance pupil's plane). The part met
just outside that radius is the one that limits the beam: the diaphragm when the mount realises
the design; with a radius of 0 the part that stands in the beam on the axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from embreex import rtcore_scene as rtcs
from embreex.mesh_construction import TriangleMesh

from lensmount.mesh import TaggedMesh
from lensmount.optics.paraxial import marginal_start, paraxial
from lensmount.optics.prescription import Prescription
from lensmount.optics.realrays import trace

AZIMUTHS = 48
BISECTIONS = 28  # rho to (1.5 EPD/2) / 2**28: far below any facet error
_EMBREE_MISS = 1e30


@dataclass
class RealisedPupil:
    """diameter (mm, equal-area circle), radii (K,) per azimuth (mm), limiting part names (K,),
    and the design's entrance pupil diameter (mm) for comparison. From a finite object also the
    object-space numerical aperture realised and designed (None at infinity); the radii are then
    where the rays cross the paraxial entrance pupil's plane."""

    diameter: float
    radii: np.ndarray
    limited_by: list[str]
    design_diameter: float
    object_na: float | None = None
    design_object_na: float | None = None

    @property
    def relative_error(self) -> float:
        return self.diameter / self.design_diameter - 1.0


class MountHits:
    """Embree scene of every non-optical triangle; `blocked(a, b)`: does segment a→b meet one?"""

    def __init__(self, mesh: TaggedMesh):
        optical = np.array([t.role == "optical" for t in mesh.tag_table])[mesh.tags]
        self.tri = np.flatnonzero(~optical)
        self.part = np.array([t.part for t in mesh.tag_table])[mesh.tags[self.tri]]
        # centred float32 coordinates keep ~µm over a 300 mm assembly
        self.centre = 0.5 * (mesh.vertices.min(0) + mesh.vertices.max(0))
        self.scene = rtcs.EmbreeScene()
        TriangleMesh(self.scene, (mesh.vertices - self.centre).astype(np.float32),
                     mesh.triangles[self.tri].astype(np.int32))

    def first(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Index into self.part of the first triangle on each segment a→b, -1 for none: (N,)."""
        seg = b - a
        length = np.linalg.norm(seg, axis=1)
        d = seg / np.maximum(length, 1e-300)[:, None]
        res = self.scene.run((a - self.centre).astype(np.float32), d.astype(np.float32),
                             query="INTERSECT", output=1)
        prim = res["primID"].astype(np.int64)
        t = res["tfar"].astype(np.float64)
        return np.where((prim >= 0) & (t < _EMBREE_MISS) & (t <= length) & (length > 0), prim, -1)


def _first_block(hits: MountHits, p: Prescription, rho: np.ndarray, phi: np.ndarray, wl: float, z0: float):
    """Per ray: index of the first mount triangle on its path (-1: reaches the image). rho: the
    height at infinity, the slope from a finite object's axial point."""
    across = np.column_stack([rho * np.cos(phi), rho * np.sin(phi)])
    if p.finite_object:
        o = np.tile([0.0, 0.0, -p.object_distance], (len(rho), 1))
        d = np.column_stack([across, np.ones(len(rho))])
    else:
        o = np.column_stack([across, np.full(len(rho), z0)])
        d = np.tile([0.0, 0.0, 1.0], (len(rho), 1))
    rays = trace(p, o, d, wl, clip=False)
    path = np.concatenate([o[None], rays.points], axis=0)  # (S+2, N, 3)
    first = np.full(len(rho), -1)
    for a, b in zip(path[:-1], path[1:]):
        todo = first < 0
        if not todo.any():
            break
        first[todo] = hits.first(a[todo], b[todo])
    return np.where(rays.vignetted & (first < 0), -2, first)  # -2: the lens itself lost the ray


def realised_entrance_pupil(prescription: Prescription, mesh: TaggedMesh, azimuths: int = AZIMUTHS) -> RealisedPupil:
    """Measure the entrance pupil the mesh lets through (see the module docstring)."""
    p = prescription
    par = paraxial(p)
    design = float(par.epd)
    # what the bisection varies: the height at infinity, the slope from a finite object's axial point
    span = abs(marginal_start(p, design, par.entrance_pupil_z)[1]) if p.finite_object else 0.5 * design
    wl = p.primary_wavelength_um
    hits = MountHits(mesh)
    z0 = float(mesh.vertices[:, 2].min()) - 1.0  # in front of the hood's mouth
    phi = (np.arange(azimuths) + 0.5) * 2 * np.pi / azimuths
    lo, hi = np.zeros(azimuths), np.full(azimuths, 1.5 * span)
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        ok = _first_block(hits, p, mid, phi, wl, z0) == -1
        lo, hi = np.where(ok, mid, lo), np.where(ok, hi, mid)
    k = _first_block(hits, p, hi * (1 + 1e-6), phi, wl, z0)
    limited = [str(hits.part[i]) if i >= 0 else ("lens aperture" if i == -2 else "none") for i in k]
    if not p.finite_object:
        return RealisedPupil(float(2.0 * np.sqrt(np.mean(lo ** 2))), lo, limited, design)
    # the cone of the same solid angle, 2π(1 − cos θ), averaged over the azimuths
    cos_t = np.mean(1.0 / np.sqrt(1.0 + lo ** 2))
    slope = float(np.sqrt(max(1.0 / cos_t ** 2 - 1.0, 0.0)))
    return RealisedPupil(design * slope / span, lo * design / (2.0 * span), limited, design,
                         float(slope / np.sqrt(1.0 + slope ** 2)), float(span / np.sqrt(1.0 + span ** 2)))


__all__ = ["realised_entrance_pupil", "RealisedPupil", "MountHits"]
