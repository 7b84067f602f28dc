"""The lens model: interfaces and the gaps between them (as optiland and rayoptics do).

Lengths in mm, wavelengths in µm. Surface 1 is the first surface after the object;
its vertex sits at z = 0 and light enters travelling +z. The object is at infinity
(the sun) unless `object_distance` says otherwise; the image plane sits
`surfaces[-1].thickness` after the last surface. A mirror reverses the direction of
travel: as in Zemax, the thicknesses after it are negative while light runs -z. Paraxial
and derived quantities are computed (lensmount.optics.paraxial), never stored here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

from lensmount.optics.placement import Frame
from lensmount.optics.profiles import Profile
from lensmount.optics.qtype import QType

AIR = "AIR"


@dataclass(frozen=True)
class Surface:
    """One optical interface and the gap after it.

    Args:
        radius: vertex radius of curvature in mm; `math.inf` for a plane.
        thickness: axial distance to the next surface (or to the image plane
            after the last surface), mm.
        material: medium after the surface: `AIR`, a catalogue glass
            (`N-BK7`, `SCHOTT:N-BK7`) or a model glass `"1.5168/64.17"` (n_d/V_d).
            For a mirror it is the medium the light returns into (the one in front).
        conic: conic constant k (0 sphere, -1 paraboloid).
        aspheric: even-asphere coefficients (A4, A6, A8, ...) of r^4, r^6, ... in mm units.
        qtype: a Forbes Q-type departure (Qbfs or Qcon) added to the base conic, or None.
        clear_semi_diameter: semi-diameter the light uses, mm; None = computed
            from the real-ray trace (lensmount.optics.apertures).
        mechanical_semi_diameter: outer semi-diameter of the glass, mm; None =
            clear semi-diameter plus the mount's edge allowance.
        is_stop: this surface is the aperture stop.
        coating: coating name (`perfect-ar`, `uncoated`, `mgf2-quarter-wave`, `R=0.01`) or None.
        mirror: the surface reflects (Zemax `GLAS MIRROR`) instead of refracting.
    """

    radius: float = math.inf
    thickness: float = 0.0
    material: str = AIR
    conic: float = 0.0
    aspheric: tuple[float, ...] = ()
    clear_semi_diameter: float | None = None
    mechanical_semi_diameter: float | None = None
    is_stop: bool = False
    coating: str | None = None
    mirror: bool = False
    qtype: QType | None = None

    @property
    def curvature(self) -> float:
        return 0.0 if math.isinf(self.radius) else 1.0 / self.radius

    @property
    def vertex_curvature(self) -> float:
        """The paraxial curvature (1/mm): the base's, plus what a Q-type departure adds at the vertex."""
        return Profile.of(self).vertex_curvature

    @property
    def is_plane(self) -> bool:
        return math.isinf(self.radius) and not any(self.aspheric) and self.qtype is None

    @property
    def is_air_after(self) -> bool:
        return self.material.upper() == AIR


@dataclass(frozen=True)
class Aperture:
    """System aperture: entrance pupil diameter (mm), image-space f-number (efl / epd),
    or object-space numerical aperture (finite objects; n sin u of the axial marginal ray)."""

    kind: Literal["epd", "fno", "object_na"]
    value: float


@dataclass(frozen=True)
class Prescription:
    """A sequential lens, object at infinity or at a finite distance.

    Args:
        surfaces: surfaces 1..N in order from the object (object and image excluded).
        wavelengths_um: wavelengths in µm.
        wavelength_weights: relative weights, same length.
        primary_wavelength: index into `wavelengths_um` of the design wavelength.
        field_angles_deg: field angles in degrees (0 first), measured in the y-z plane.
            For a finite object: the object-space angles of the paraxial chief rays
            (0 for a telecentric object space); the fields themselves are heights.
        aperture: entrance pupil diameter or f-number.
        name: a human name for reports.
        object_distance: object plane to surface 1's vertex, mm; `math.inf` for an
            object at infinity.
        object_heights_mm: the fields of a finite object, heights on the object plane.
        vignetting: the designer's vignetting factors, one row (VDX, VDY, VCX, VCY, VAN) per
            entry of `field_values` (Zemax's: a pupil point (x, y) of that field becomes
            (VDX + x (1 - VCX), VDY + y (1 - VCY)), turned by VAN degrees; y points along the
            field); () for none. Automatic clear semi-diameters come from the beam they leave.
        object_telecentric: a finite object seen from telecentric object space (Zemax's FTYP
            flag): every field's chief ray runs parallel to the axis and its rays fill the cone
            of the object-space NA (direction cosines NA times the pupil point), whatever the
            stop. Only the real-ray aiming follows it: the paraxial data stay the stop's (a lens
            designed telecentric has its stop at the front group's focus, so its paraxial entrance
            pupil is far away anyway).
        glass_catalogs: the user's glass catalogues (.agf paths) the materials were found in
            (a material `NAME:GLASS` names one by its file's stem; lensmount.optics.glass).
        frames: for a lens whose surfaces do not share one axis (folded, tilted, decentred), the
            placement of every surface and then of the image plane (lensmount.optics.placement);
            each thickness runs along the local z of its surface. () for a coaxial lens, whose
            surfaces sit on the z axis at `vertex_z`.
    """

    surfaces: tuple[Surface, ...]
    aperture: Aperture
    wavelengths_um: tuple[float, ...] = (0.5875618,)
    wavelength_weights: tuple[float, ...] = (1.0,)
    primary_wavelength: int = 0
    field_angles_deg: tuple[float, ...] = (0.0,)
    name: str = "lens"
    object_distance: float = math.inf
    object_heights_mm: tuple[float, ...] = ()
    vignetting: tuple[tuple[float, float, float, float, float], ...] = ()
    object_telecentric: bool = False
    glass_catalogs: tuple[str, ...] = ()
    frames: tuple[Frame, ...] = ()

    @property
    def finite_object(self) -> bool:
        return math.isfinite(self.object_distance)

    @property
    def field_values(self) -> tuple[float, ...]:
        """What the ray aiming takes as a field: angles (deg) at infinity, object heights (mm) otherwise."""
        return self.object_heights_mm if self.finite_object else self.field_angles_deg

    @property
    def mirror_surfaces(self) -> tuple[int, ...]:
        """0-based indices of the mirror surfaces, in sequence order."""
        return tuple(i for i, s in enumerate(self.surfaces) if s.mirror)

    @property
    def has_mirrors(self) -> bool:
        return bool(self.mirror_surfaces)

    @property
    def travel(self) -> tuple[int, ...]:
        """Direction of travel (+1 along +z, -1 along -z) in the space after each surface."""
        sign, out = 1, []
        for s in self.surfaces:
            sign = -sign if s.mirror else sign
            out.append(sign)
        return tuple(out)

    @property
    def primary_wavelength_um(self) -> float:
        return self.wavelengths_um[self.primary_wavelength]

    @property
    def stop_index(self) -> int:
        """0-based index of the stop surface in `surfaces`."""
        for i, s in enumerate(self.surfaces):
            if s.is_stop:
                return i
        raise ValueError("prescription has no stop surface")

    @property
    def vertex_z(self) -> tuple[float, ...]:
        """z of every surface vertex, surface 1 at z = 0."""
        z, out = 0.0, []
        for s in self.surfaces:
            out.append(z)
            z += s.thickness
        return tuple(out)

    @property
    def image_z(self) -> float:
        return sum(s.thickness for s in self.surfaces)

    @property
    def max_field_deg(self) -> float:
        return max(abs(f) for f in self.field_angles_deg)

    @property
    def image_medium(self) -> str:
        """The medium the image is formed in: the material after the last surface (`AIR` for most
        lenses; an immersion objective's water or oil, `"1.333/55.8"` or a catalogue liquid)."""
        return self.surfaces[-1].material

    @property
    def immersion_face(self) -> int | None:
        """0-based index of the face the image medium begins at, None in air.

        The image medium fills the space from this face to the image plane and is no part of the
        lens: the detector (the specimen plane) sits in optical contact with it, as an immersion
        objective's water or oil does, so it is not a lens element the mount holds (a cover glass in
        front of it is one: glass between two faces). Any surfaces after this face in the same
        medium are dummies in the liquid."""
        if self.surfaces[-1].is_air_after:
            return None
        medium = self.image_medium.upper()
        i = len(self.surfaces) - 1
        while i > 0 and self.surfaces[i - 1].material.upper() == medium and not self.surfaces[i - 1].mirror:
            i -= 1
        return i

    def holds_glass_after(self, i: int) -> bool:
        """Surface i (0-based) is followed by a lens element's glass: not air, not the image medium."""
        face = self.immersion_face
        return not self.surfaces[i].is_air_after and (face is None or i < face)

    def material_before(self, i: int) -> str:
        """Medium in front of surface i (0-based): air before surface 1."""
        return AIR if i == 0 else self.surfaces[i - 1].material

    def lens_groups(self) -> list[tuple[int, ...]]:
        """Runs of surfaces bounding glass: (first, ..., last) 0-based indices.

        A singlet is (i, i+1); a cemented doublet (i, i+1, i+2). The surfaces inside
        a run with glass on both sides are cemented interfaces. The image medium after
        `immersion_face` is no element: a cover glass in contact with it ends its run there.
        """
        groups, current = [], []
        for i, s in enumerate(self.surfaces):
            if self.holds_glass_after(i):
                if not current:
                    current = [i]
                current.append(i + 1)
            elif current:
                groups.append(tuple(current))
                current = []
        if current:
            groups.append(tuple(current))
        return groups

    def with_surfaces(self, surfaces) -> "Prescription":
        return replace(self, surfaces=tuple(surfaces))

    def with_clear_semi_diameters(self, semi_diameters) -> "Prescription":
        return self.with_surfaces(
            replace(s, clear_semi_diameter=float(h)) for s, h in zip(self.surfaces, semi_diameters)
        )


__all__ = ["AIR", "Surface", "Aperture", "Prescription"]
