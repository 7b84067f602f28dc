"""The Scene: everything the tracer needs, as plain data (no file access, no tracing).

    Scene = TaggedMesh (mount, lens solids, extra objects)
          + analytic optical surfaces (profile, media on both sides, coating)
          + one BSDF per face tag (None for optical faces)
          + source + detector + wavelengths + effects

Each field, with its shape and unit: the `Scene` docstring below.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lensmount.mesh import TaggedMesh
from lensmount.optics.profiles import Profile
from lensmount.physics.detector import Detector
from lensmount.physics.interfaces import Coating
from lensmount.physics.sources import Source


@dataclass(frozen=True)
class Effects:
    """Which light paths a run builds (DESIGN.md, "Effects"; the planner, `integrators.plan`).

    scatter: mechanical faces scatter with their finish (else every mechanical face absorbs).
    ghosts: Fresnel reflections at glass are followed (else the ray transmits with weight T).
    direct: photons reaching the detector without scattering are recorded.
    scatterers: with scatter on, the faces that scatter as selectors ("part:NAME", "role:ROLE",
        "kind:KIND", "finish:NAME"); every other mechanical face ends the path. () = every face.
    ghost_order: with ghosts on, 2 (two-reflection ghosts) or 3 (four-reflection ones too: three
        reflections send the light back out of the front; `trace.ghosts.reflections_of_order`).
    absorption: bulk absorption of the glass along every path inside it, exp(-a(λ) L) with a
        from the catalogue (off for comparisons with lossless references).
    """

    scatter: bool = True
    ghosts: bool = False
    direct: bool = False
    scatterers: tuple[str, ...] = ()
    ghost_order: int = 2
    absorption: bool = True

    def __post_init__(self):
        if self.ghost_order not in (2, 3):
            raise ValueError(f"Effects.ghost_order must be 2 or 3, got {self.ghost_order}")


# The on/off switches, in the order summaries list them (scatterers and ghost_order refine them).
EFFECT_NAMES = ("scatter", "ghosts", "direct", "absorption")


def faces_selected(selector: str, tag_table, finish_of_tag) -> np.ndarray:
    """(n_tags,) bool: the faces one scatter selector names. `finish:` matches the finish the
    scene gives the face (`finish_of_tag`), the one that scatters; `surface:N` a mirror's coated
    face (surface N, 1-based). Optical faces take part only where the scene gives them a finish
    (a mirror's coated face, `[assign] "surface:N"`): glass has nothing to scatter with."""
    prefix, _, value = selector.partition(":")
    finishes = list(finish_of_tag) or [t.finish for t in tag_table]
    if prefix == "finish":
        names = finishes
    elif prefix == "surface":
        names = [str(t.surface + 1) if t.role == "optical" else "" for t in tag_table]
    else:
        names = [str(getattr(t, prefix)) for t in tag_table]
    return np.array([n == value and (t.role != "optical" or (bool(finish_of_tag) and f != ""))
                     for n, t, f in zip(names, tag_table, finishes)], bool)


def scatterer_mask(effects: Effects, tag_table, finish_of_tag) -> np.ndarray:
    """(n_tags,) bool: faces the effects let scatter (all with `scatterers` empty; none with scatter off)."""
    n = len(tag_table)
    if not effects.scatter:
        return np.zeros(n, bool)
    if not effects.scatterers:
        return np.ones(n, bool)
    mask = np.zeros(n, bool)
    for sel in effects.scatterers:
        mask |= faces_selected(sel, tag_table, finish_of_tag)
    return mask


def optical_faces(tag_table) -> np.ndarray:
    """(n_tags,) bool: the faces of optical surfaces (glass, and mirrors' coated faces)."""
    return np.array([t.role == "optical" for t in tag_table], bool)


def scattering_tags(scene) -> np.ndarray:
    """(n_tags,) bool: faces where light scatters on (BSDF neither missing nor black, and a
    scatterer of the scene's effects: `scatterer_mask`); a mirror's coated face among them is
    where the tracer branches to its finish (`Tracer.next_event`)."""
    on = np.array([b is not None and not b.is_black for b in scene.bsdf_of_tag], bool)
    return on & scatterer_mask(scene.effects, scene.mesh.tag_table, scene.finish_of_tag)


def scattering_mirror_tags(scene) -> dict[int, int]:
    """{mirror surface index (0-based): tag of its coated face} where the scene lets that face
    scatter (`scattering_tags`); its BSDF is a `physics.bsdf.mirror_finish.MirrorFinish`. Mirrors without one
    reflect specularly only."""
    mirrors = {s.index for s in scene.optical if s.mirror}
    if not mirrors:  # a refracting lens: no face to look at
        return {}
    scatters = scattering_tags(scene)
    out: dict[int, int] = {}
    for t, tag in enumerate(scene.mesh.tag_table):
        if scatters[t] and tag.role == "optical" and tag.surface in mirrors:
            out.setdefault(tag.surface, t)
    return out


@dataclass(frozen=True, eq=False)
class OpticalSurface:
    """One analytic optical interface.

    index: 0-based prescription surface index (the `surface` of its mesh tags).
    z_vertex: vertex z in the assembly frame, mm.
    profile: sag/normal/intersect in the local frame (vertex at the origin).
    clear_semi_diameter, mechanical_semi_diameter: mm.
    n_before, n_after: (W,) refractive index on the −z / +z side of the surface per scene wavelength
        (for a surface the light reaches travelling −z, after a mirror, "before" is the file's medium
        after it: the tracer picks the pair by the sign of d·n, not by the order in the file).
    coating: how much it reflects.
    absorption_before, absorption_after: (W,) bulk absorption coefficient (1/mm) of the media
        in front of / behind the surface (0 in air), paired with n_before / n_after.
    mirror: the surface reflects every ray (Zemax GLAS MIRROR) with reflectance
        `physics.interfaces.mirror_reflectance(coating)`; nothing is transmitted. Its coated face may
        carry a scatter finish (`[assign] "surface:N"`, its tag's BSDF).
    """

    index: int
    z_vertex: float
    profile: Profile
    clear_semi_diameter: float
    n_before: np.ndarray
    n_after: np.ndarray
    coating: Coating
    absorption_before: np.ndarray
    absorption_after: np.ndarray
    mechanical_semi_diameter: float = math.inf
    mirror: bool = False


@dataclass(frozen=True)
class FrontOpening:
    """The assembly's front aperture: light from the source enters here (hood mouth or surface 1)."""

    z: float
    radius: float


@dataclass(eq=False)
class Scene:
    """Pure data for one simulation.

    Every field the physics reads is required and checked here: a scene built by a
    script cannot silently drop the 1/n² factor, the stray-fraction normalisation or
    the effects it asked for.

    mesh: tagged triangles (mm, assembly frame).
    optical: analytic surfaces, any order; `optical_of_surface[i]` finds surface i.
    bsdf_of_tag: (n_tags,) BSDF per mesh tag, None for optical tags (a mirror's coated face with a
        finish: `physics.bsdf.mirror_finish.MirrorFinish` of it).
    source: SunSource | CollimatedSource.
    detector: Detector.
    wavelengths_um: (W,).
    effects: Effects.
    entrance_pupil_area_mm2: π (EPD/2)², for the stray fraction (> 0).
    solid_index_of_tag: (n_tags, W) refractive index inside the solid each tag bounds (a lens
        part's glass; 1 for mechanical parts), so a scatter seen from inside glass is known
        (`scene.build.solid_index_of_tag` computes it from the prescription).
    solid_absorption_of_tag: (n_tags, W) bulk absorption coefficient (1/mm) inside the solid
        each tag bounds (0 for mechanical parts; `scene.build.solid_absorption_of_tag`): a path
        that ends on a lens part's edge from inside is absorbed along its length.
    front_opening: FrontOpening, where the source's light enters (information).
    finish_of_tag: finish name per tag, for reports (empty, or one per tag).
    description: the scene file's description.
    warnings: legal but suspicious inputs noticed while building (printed and written to
        summary.json by the CLI).
    field_of_view_deg: the largest off-axis angle the detector images (the lens's field or the
        detector's half diagonal through the focal length, the larger; `scene.build.imaged_field_deg`),
        180 when unknown; the planner skips the direct path for a source well beyond it.
    """

    mesh: TaggedMesh
    optical: list[OpticalSurface]
    bsdf_of_tag: list
    source: Source
    detector: Detector
    wavelengths_um: np.ndarray
    effects: Effects
    entrance_pupil_area_mm2: float
    solid_index_of_tag: np.ndarray
    solid_absorption_of_tag: np.ndarray
    front_opening: FrontOpening | None = None
    finish_of_tag: list[str] = field(default_factory=list)
    description: str = ""
    warnings: list[str] = field(default_factory=list)
    field_of_view_deg: float = 180.0

    def __post_init__(self):
        n_tags = len(self.mesh.tag_table)
        self.wavelengths_um = np.atleast_1d(np.asarray(self.wavelengths_um, np.float64))
        w = len(self.wavelengths_um)
        if w == 0 or not np.all(np.isfinite(self.wavelengths_um)):
            raise ValueError("Scene.wavelengths_um must hold at least one finite wavelength")
        if not isinstance(self.effects, Effects):
            raise TypeError(f"Scene.effects must be an Effects, got {type(self.effects).__name__}")
        if len(self.bsdf_of_tag) != n_tags:
            raise ValueError(f"Scene.bsdf_of_tag has {len(self.bsdf_of_tag)} entries for {n_tags} mesh tags")
        index = np.asarray(self.solid_index_of_tag, np.float64)
        if index.shape != (n_tags, w) or not np.all(np.isfinite(index)) or np.any(index < 1.0):
            raise ValueError(f"Scene.solid_index_of_tag must be a finite (n_tags, W) = ({n_tags}, {w}) array "
                             f"of indices >= 1, got shape {index.shape}")
        self.solid_index_of_tag = index
        alpha = np.asarray(self.solid_absorption_of_tag, np.float64)
        if alpha.shape != (n_tags, w) or not np.all(np.isfinite(alpha)) or np.any(alpha < 0.0):
            raise ValueError(f"Scene.solid_absorption_of_tag must be a finite (n_tags, W) = ({n_tags}, {w}) array "
                             f"of coefficients >= 0 (1/mm), got shape {alpha.shape}")
        self.solid_absorption_of_tag = alpha
        area = float(self.entrance_pupil_area_mm2)
        if not (math.isfinite(area) and area > 0.0):
            raise ValueError(f"Scene.entrance_pupil_area_mm2 must be finite and > 0, got {area}")
        if self.finish_of_tag and len(self.finish_of_tag) != n_tags:
            raise ValueError(f"Scene.finish_of_tag has {len(self.finish_of_tag)} names for {n_tags} mesh tags")
        for s in self.optical:
            if len(np.atleast_1d(s.n_before)) != w or len(np.atleast_1d(s.n_after)) != w:
                raise ValueError(f"optical surface {s.index + 1}: n_before/n_after need one index per wavelength ({w})")
            for a in (s.absorption_before, s.absorption_after):
                a = np.atleast_1d(np.asarray(a, np.float64))
                if len(a) != w or not np.all(np.isfinite(a)) or np.any(a < 0.0):
                    raise ValueError(f"optical surface {s.index + 1}: absorption_before/after need one finite "
                                     f"coefficient >= 0 per wavelength ({w})")

    @property
    def part_names(self) -> list[str]:
        return self.mesh.parts

    def optical_of_surface(self) -> dict[int, OpticalSurface]:
        return {s.index: s for s in self.optical}


__all__ = ["Effects", "EFFECT_NAMES", "OpticalSurface", "FrontOpening", "Scene", "faces_selected", "scatterer_mask",
           "optical_faces", "scattering_tags", "scattering_mirror_tags"]
