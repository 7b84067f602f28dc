"""The Scene: everything the tracer needs, as plain data (no file access, no tracing).

    Scene = TaggedMesh (mount, lens solids, extra objects)
          + analytic optical surfaces (profile, media on both sides, coating)
          + one BSDF per face tag (None for optical faces)
          + source + detector + wavelengths + effects

Fields follow docs/architecture.md; additions are marked "(addition)".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lensmount.cad.mesh import TaggedMesh
from lensmount.optics.profiles import Profile
from lensmount.trace.detector import Detector
from lensmount.trace.interfaces import Coating


@dataclass(frozen=True)
class Effects:
    """Which light paths a run builds (DESIGN.md, "Effects").

    scatter: mechanical faces scatter with their finish (else every mechanical face absorbs).
    ghosts: Fresnel reflections at glass (a reflection branch chosen with probability R).
    direct: photons reaching the detector without scattering are recorded.
    """

    scatter: bool = True
    ghosts: bool = False
    direct: bool = False


@dataclass(frozen=True, eq=False)
class OpticalSurface:
    """One analytic optical interface.

    index: 0-based prescription surface index (the `surface` of its mesh tags).
    z_vertex: vertex z in the assembly frame, mm.
    profile: sag/normal/intersect in the local frame (vertex at the origin).
    clear_semi_diameter, mechanical_semi_diameter: mm.
    n_before, n_after: (W,) refractive index in front of / behind the surface per scene wavelength.
    coating: how much it reflects.
    """

    index: int
    z_vertex: float
    profile: Profile
    clear_semi_diameter: float
    n_before: np.ndarray
    n_after: np.ndarray
    coating: Coating
    mechanical_semi_diameter: float = math.inf  # (addition)


@dataclass(frozen=True)
class FrontOpening:
    """The assembly's front aperture: light from the source enters here (hood mouth or surface 1)."""

    z: float
    radius: float


@dataclass(eq=False)
class Scene:
    """Pure data for one simulation.

    mesh: tagged triangles (mm, assembly frame).
    optical: analytic surfaces, any order; `optical_of_surface[i]` finds surface i.
    bsdf_of_tag: (n_tags,) BSDF per mesh tag, None for optical tags.
    source: SunSource | CollimatedSource.
    detector: Detector.
    wavelengths_um: (W,).
    effects: Effects.
    front_opening: FrontOpening (addition).
    entrance_pupil_area_mm2: π (EPD/2)², for the stray fraction (addition).
    finish_of_tag: finish name per tag, for reports (addition).
    description: the scene file's description (addition).
    solid_index_of_tag: (n_tags, W) refractive index inside the solid each tag bounds (a lens
        part's glass; 1 for mechanical parts), so a scatter seen from inside glass is known.
    """

    mesh: TaggedMesh
    optical: list[OpticalSurface]
    bsdf_of_tag: list
    source: object
    detector: Detector
    wavelengths_um: np.ndarray
    effects: Effects = field(default_factory=Effects)
    front_opening: FrontOpening | None = None
    entrance_pupil_area_mm2: float = 0.0
    finish_of_tag: list[str] = field(default_factory=list)
    description: str = ""
    solid_index_of_tag: np.ndarray | None = None

    @property
    def part_names(self) -> list[str]:
        return self.mesh.parts

    def optical_of_surface(self) -> dict[int, OpticalSurface]:
        return {s.index: s for s in self.optical}


__all__ = ["Effects", "OpticalSurface", "FrontOpening", "Scene"]
