"""Lens elements edged where they can exist: an element whose faces would meet inside the beam.

A designer who vignettes the rim of the outer field may leave an element whose faces cross
inside the semi-diameter Zemax computes for it (US 5,831,776's element 8: faces meeting at
114.1 mm, the 48 mm field's beam reaching 119.3 mm). An optician edges such an element where
its edge still has the minimum thickness and accepts the rim rays it loses. `clip_crossing_elements`
does that for semi-diameters left automatic (no clear or mechanical semi-diameter in the file)
and measures what the clip vignettes with real rays; it refuses when that changes the design's
aperture: any ray of the on-axis beam, or more than `MAX_CLIP_VIGNETTING` of a field's pupil.
A semi-diameter the file gives is the designer's size: faces crossing inside it stay an error
(design.lens._check_crossings).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from lensmount.design.mount import MountSpec
from lensmount.errors import InputError
from lensmount.optics.apertures import pupil_lost_at, with_clear_semi_diameters
from lensmount.optics.prescription import Prescription
from lensmount.optics.profiles import Profile

# A clip that takes more than a tenth of a field's designed pupil is a design decision, not the
# import's: below it the loss is smaller than the fall-off designers take at the field edge with
# their own vignetting factors (commonly 10-50 %), and the on-axis beam (aperture, F/#) is never
# touched. docs/lens-toml.md.
MAX_CLIP_VIGNETTING = 0.10


def clip_gap(spec: MountSpec | None = None) -> float:
    """The glass kept between the faces at a clipped height, mm: the mount's minimum edge
    ([checks] min_thickness_mm) after its two protective chamfers (lens_edge.chamfer_mm), so that
    the mount planner can edge the element there with a flat bevel; the default mount's without `spec`."""
    spec = MountSpec() if spec is None else spec
    return spec.checks.min_thickness_mm + 2.0 * spec.lens_edge.chamfer_mm
_SAMPLES = 256


@dataclass(frozen=True)
class EdgeClip:
    """One element edged inside the beam.

    Args:
        elements: 1-based element numbers: (k,) for an element's own faces, (k, k + 1) for
            two neighbours' faces across air.
        surfaces: the two faces, 0-based.
        meet: height where the faces meet, mm.
        needed: the beam's automatic semi-diameters of both faces, mm.
        height: the clear semi-diameter the automatic faces are clipped to, mm.
        gap: the glass edge (or air gap) kept at `height`, mm (`clip_gap`).
        fields: the fields measured (the file's, on-axis included), deg or mm.
        lost: per field, the fraction of its designed pupil the clip stops.
        field_unit: "°" (object at infinity) or "mm" (object heights).
    """

    elements: tuple[int, ...]
    surfaces: tuple[int, int]
    meet: float
    needed: tuple[float, float]
    height: float
    gap: float
    fields: tuple[float, ...]
    lost: tuple[float, ...]
    field_unit: str

    def vignetting(self, lost=None) -> str:
        lost = self.lost if lost is None else lost
        return ", ".join(f"{100 * v:.2f} % at {f:.3g} {self.field_unit}".replace(" °", "°")
                         for f, v in zip(self.fields, lost))

    def whose(self) -> str:
        if len(self.elements) == 1:
            return f"the faces of element {self.elements[0]}"
        return f"the faces of elements {self.elements[0]} and {self.elements[1]} across the air gap"

    def beam(self) -> float:
        """The beam's semi-diameter the faces must share: in glass the larger, across air the smaller."""
        return max(self.needed) if len(self.elements) == 1 else min(self.needed)

    def faces_meet(self) -> str:
        """Where the faces meet, against the beam: inside it, or beyond it but closer than `gap` inside."""
        beam = f"the {self.beam():.4g} mm the beam of the full field reaches"
        if self.meet < self.beam():
            return f"meet {self.meet:.4g} mm from the axis, inside {beam}"
        return f"come closer than {self.gap:g} mm inside {beam} (they meet {self.meet:.4g} mm from the axis)"

    def message(self) -> str:
        a, b = self.surfaces
        what = "its edge" if len(self.elements) == 1 else "the air gap"
        return (f"surfaces {a + 1} and {b + 1} are edged at {self.height:.4g} mm: {self.whose()} {self.faces_meet()}, "
                f"and at {self.height:.4g} mm {what} is {self.gap:g} mm (the minimum edge, [checks] "
                f"min_thickness_mm, after two protective chamfers, lens_edge.chamfer_mm); the clip vignettes "
                f"the designed pupil by {self.vignetting()}")


def face_gap(p: Prescription, i: int, r: np.ndarray) -> np.ndarray:
    """Axial distance between faces i and i + 1 (glass or air) at heights r, along the light (inf
    where a profile does not reach; negative where they cross)."""
    z, pa, pb = p.vertex_z, Profile.of(p.surfaces[i]), Profile.of(p.surfaces[i + 1])
    gap = ((z[i + 1] + pb.sag(r * r)) - (z[i] + pa.sag(r * r))) * p.travel[i]
    return np.where(np.isfinite(gap), gap, np.inf)


def height_at_gap(p: Prescription, i: int, lo: float, hi: float, thickness: float) -> float:
    """The height in [lo, hi] where the gap falls to `thickness` (gap(lo) >= thickness > gap(hi)),
    by bisection to the last bit: the largest height found with gap >= thickness."""
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if face_gap(p, i, np.array([mid]))[0] >= thickness else (lo, mid)
    return lo


def _element_numbers(p: Prescription) -> list[int]:
    """1-based element number of the glass after each surface (0 in air and in the image medium)."""
    out, n = [], 0
    for i in range(len(p.surfaces)):
        n += p.holds_glass_after(i)
        out.append(n if p.holds_glass_after(i) else 0)
    return out


def _first_crossing(p: Prescription, clippable: list[bool], gap: float, thin: bool = False):
    """(i, needed, meet, height) of the first pair of faces i, i + 1 that meet inside the beam's
    semi-diameters (in glass the larger, across air the smaller, as design.lens._check_crossings),
    or with `thin` an element's faces that come closer than `gap` there, one of them clippable, and
    the height where the gap between them is still `gap`; None. `meet`: where the faces meet (at
    most where both end)."""
    for i in range(len(p.surfaces) - 1):
        if not (clippable[i] or clippable[i + 1]):
            continue
        needed = (float(p.surfaces[i].clear_semi_diameter), float(p.surfaces[i + 1].clear_semi_diameter))
        h = max(needed) if not p.surfaces[i].is_air_after else min(needed)
        reach = min(Profile.of(p.surfaces[j]).max_radius() for j in (i, i + 1))
        r = np.linspace(0.0, min(h, reach), _SAMPLES)
        along = face_gap(p, i, r)
        least = gap if thin and not p.surfaces[i].is_air_after else 0.0
        if along.min() >= least - 1e-9 or along[0] < gap:   # apart enough, or too thin on the axis: nothing to edge
            continue
        k = int(np.argmax(along < gap))
        height = height_at_gap(p, i, r[k - 1], r[k], gap)
        if not p.surfaces[i].is_air_after and any(not clippable[j] and needed[j - i] > height for j in (i, i + 1)):
            continue   # the element's edge is a size the file gives (or the stop's): design.lens refuses it
        out = np.linspace(0.0, reach, 4 * _SAMPLES) if along.min() >= -1e-9 else r   # they meet beyond the beam
        crossed = face_gap(p, i, out) < -1e-9
        m = int(np.argmax(crossed))
        return i, needed, height_at_gap(p, i, out[m - 1], out[m], 0.0) if crossed.any() else reach, height
    return None


def clip_crossing_elements(raw: Prescription, margin_mm: float, file: str, gap: float | None = None,
                           max_vignetting: float | None = MAX_CLIP_VIGNETTING, thin: bool = False
                           ) -> tuple[Prescription, tuple[EdgeClip, ...]]:
    """`raw` with its automatic semi-diameters from real rays (apertures.with_clear_semi_diameters),
    where faces meet inside them (an element's own, or two neighbours' across air) those faces
    edged at the height where the gap between them is `gap`, and the clips made. Each clip is
    an aperture of the lens, so the automatic semi-diameters behind it follow the beam it leaves.
    Raises InputError (one paragraph) when a clip would change the design's aperture
    (`changes_aperture` with `max_vignetting`); None: the glass decides, whatever the clips cost
    (the mount's `lens_edge.allow_vignetting`). `thin`: an element whose faces come closer than `gap`
    inside the beam without crossing is edged there too (its glass ends where the mount's edge can)."""
    gap = clip_gap() if gap is None else gap
    stop = raw.stop_index
    clippable = [j != stop and s.clear_semi_diameter is None and s.mechanical_semi_diameter is None
                 for j, s in enumerate(raw.surfaces)]
    lens, found = raw, []
    complete = with_clear_semi_diameters(lens, margin_mm)
    for _ in range(len(raw.surfaces)):
        crossing = _first_crossing(complete, clippable, gap, thin)
        if crossing is None:
            break
        i, needed, meet, height = crossing
        surfaces = list(lens.surfaces)
        for j in (i, i + 1):
            if clippable[j] and complete.surfaces[j].clear_semi_diameter > height:
                surfaces[j] = replace(surfaces[j], clear_semi_diameter=float(height))
            clippable[j] = False
        found.append(crossing)
        lens = lens.with_surfaces(surfaces)
        complete = with_clear_semi_diameters(lens, margin_mm)
    if not found:
        return complete, ()
    fields = np.unique(np.concatenate([[0.0], np.abs(np.asarray(raw.field_values, dtype=np.float64))]))
    unit = "mm" if raw.finite_object else "°"
    numbers = _element_numbers(raw)
    clips = []
    losses = pupil_lost_at(complete, [(i, i + 1) for i, *_ in found], fields)  # one trace of the beam for all
    for (i, needed, meet, height), lost in zip(found, losses):
        elements = (numbers[i],) if numbers[i] else (numbers[i - 1], numbers[i + 1])
        clips.append(EdgeClip(elements, (i, i + 1), meet, needed, height, gap,
                              tuple(float(f) for f in fields), tuple(float(v) for v in lost), unit))
    total = lost_together(clips)
    if max_vignetting is not None and changes_aperture(clips, max_vignetting):
        clip = next((c for c in clips if c.lost[0] > 0.0), max(clips, key=lambda c: max(c.lost)))
        i = clip.surfaces[0]
        raise InputError(
            f"surfaces {i + 1} and {i + 2} cross each other: {clip.whose()} meet {clip.meet:.4g} mm from the axis, "
            f"inside the {clip.beam():.4g} mm the beam of the full field and aperture reaches; edged at "
            f"{clip.height:.4g} mm (a {gap:g} mm gap) they would vignette the designed pupil by {clip.vignetting()}"
            + (f" ({clip.vignetting(total)} with the {len(clips)} clips together)" if len(clips) > 1 else "")
            + f", which changes the design's aperture (any on-axis ray, or more than {100 * MAX_CLIP_VIGNETTING:g} % "
            "of a field's pupil)", file=file, field=f"surface[{i + 1}].thickness",
            valid=f"a thickness of at least {raw.surfaces[i].thickness - _least_gap(complete, i, clip.beam()):.4g} "
                  "mm, flatter curvatures, or clear semi-diameters the faces reach")
    return complete, tuple(clips)


def changes_aperture(clips, max_vignetting: float = MAX_CLIP_VIGNETTING) -> bool:
    """The clips together stop an on-axis ray, or more than `max_vignetting` of a field's pupil."""
    if not clips:
        return False
    total = lost_together(clips)
    return total[0] > 0.0 or max(total) > max_vignetting


def what_the_glass_allows(clips) -> str:
    """One sentence per clip for a refusal: which element, to which radius its glass allows it, and
    the vignetting per field that costs (all clips together at the end)."""
    said = []
    for c in clips:
        what = f"element {c.elements[0]}" if len(c.elements) == 1 else \
            f"the air gap between elements {c.elements[0]} and {c.elements[1]}"
        edge = "edge" if len(c.elements) == 1 else "gap"
        said.append(f"{what} can be {c.height:.4g} mm in semi-diameter at most (surfaces {c.surfaces[0] + 1} and "
                    f"{c.surfaces[1] + 1} {c.faces_meet()}; at {c.height:.4g} mm its {edge} is {c.gap:.3g} mm, the "
                    f"least the mount takes), which vignettes the designed pupil by {c.vignetting()}")
    if len(clips) > 1:
        said.append(f"all {len(clips)} together: {clips[0].vignetting(lost_together(clips))}")
    return "; ".join(said)


def lost_together(clips) -> tuple[float, ...]:
    """Per field, the share of the designed pupil all clips stop: a ray stops at one surface only,
    so the clips' losses add (at most: each is its worst wavelength's)."""
    return tuple(float(v) for v in np.sum([c.lost for c in clips], axis=0))


def clip_warnings(clips) -> list[str]:
    """What the user is told: one sentence per clip, and the loss of all of them together."""
    if not clips:
        return []
    together = "" if len(clips) == 1 else \
        f"; all {len(clips)} clips together: {clips[0].vignetting(lost_together(clips))}"
    return [c.message() for c in clips[:-1]] + [clips[-1].message() + together]


def _least_gap(p: Prescription, i: int, h: float) -> float:
    """The least glass thickness between faces i and i + 1 out to height h (negative: crossed)."""
    reach = min(Profile.of(p.surfaces[j]).max_radius() for j in (i, i + 1))
    return float(face_gap(p, i, np.linspace(0.0, min(h, reach), _SAMPLES)).min())




__all__ = ["EdgeClip", "MAX_CLIP_VIGNETTING", "clip_crossing_elements", "changes_aperture", "what_the_glass_allows",
           "clip_gap", "clip_warnings", "lost_together",
           "face_gap", "height_at_gap"]
