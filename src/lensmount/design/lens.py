"""Load and save lens prescriptions: `lens.toml` (the project's format) or Zemax `.zmx`.

`load_lens` reads, checks what a lens must satisfy to be built and traced, and
fills in automatic clear semi-diameters (real rays, Zemax's rule) where the file
gives none. Every problem is an InputError naming the file, the field or line,
and what would be valid.

Checks beyond the file's syntax:
- every material is a known glass, a model glass n_d/V_d, or AIR; the image may lie in a medium
  (an immersion objective's water or oil, `Prescription.image_medium`), but not before its last face
  against the light (a virtual image, refused);
- glass thicknesses are positive;
- exactly one stop;
- |radius| is at least the clear semi-diameter (given, or needed by the beam);
- neighbouring surfaces do not cross inside their common semi-diameter; an element whose faces
  meet inside automatic semi-diameters is edged where it can exist (design.edges), when that
  leaves the design's aperture as it is.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from lensmount.design.edges import MAX_CLIP_VIGNETTING, EdgeClip, clip_crossing_elements, face_gap, height_at_gap
from lensmount.errors import InputError
from lensmount.optics.glass import MODEL_GLASS, refractive_index, resolve_glass
from lensmount.optics.io.lens_toml import line_of_field, read_lens_toml, write_lens_toml
from lensmount.optics.io.zemax import read_zmx, read_zmx_with_notes
from lensmount.optics.io.zemax_file import ImportNote
from lensmount.optics.paraxial import AFOCAL_POWER_RATIO, paraxial
from lensmount.optics.placement import require_coaxial
from lensmount.optics.prescription import AIR, Prescription
from lensmount.optics.profiles import Profile

_CROSS_SAMPLES = 64
_CROSS_TOL = 1e-9  # mm: touching (zero edge thickness) is allowed, crossing is not
# The .agf catalogues the running command was given (`--glass-catalog`, lensmount.cli.options): every
# lens that command loads, however deep in the loop (a design folder's lens.zmx in simulate, compare,
# check, ...), searches them after its own (a lens.toml's glass_catalogs). Set for one command only.
_command_catalogs: tuple[str, ...] = ()


def use_command_glass_catalogs(paths) -> None:
    """Make `paths` (.agf files) the catalogues every lens loaded from now on searches after its own;
    () ends that (the CLI calls it when the command closes)."""
    global _command_catalogs
    _command_catalogs = tuple(str(Path(p)) for p in paths)


def load_lens(path, *, auto_clear_apertures: bool = True, margin_mm: float | None = None,
              glass_catalogs=(), afocal_ok: bool = False) -> Prescription:
    """Read `lens.toml` or `.zmx` into a validated Prescription (`load_lens_and_clips`, without the clips)."""
    return load_lens_and_clips(path, auto_clear_apertures=auto_clear_apertures, margin_mm=margin_mm,
                               glass_catalogs=glass_catalogs, afocal_ok=afocal_ok)[0]


def load_lens_and_clips(path, *, auto_clear_apertures: bool = True, margin_mm: float | None = None,
                        glass_catalogs=(), afocal_ok: bool = False, clip_edge_mm: float | None = None,
                        max_clip_vignetting: float | None = MAX_CLIP_VIGNETTING, clip_thin: bool = False,
                        placed_ok: bool = False) -> tuple[Prescription, tuple[EdgeClip, ...]]:
    """Read `lens.toml` or `.zmx` into a validated Prescription, and the elements edged inside
    the beam (design.edges: faces meeting inside automatic semi-diameters; a warning for the user).

    Args:
        path: the lens file; `.zmx` is read as Zemax, anything else as lens.toml. A
            folder means `folder/lens.toml` (or `folder/lens.zmx`).
        auto_clear_apertures: fill in clear semi-diameters the file does not give.
            Defaults to True.
        margin_mm: margin added to automatic semi-diameters; defaults to the file's
            `clear_aperture_margin_mm` (0 for .zmx).
        glass_catalogs: the user's Zemax .agf glass catalogues, searched for a glass name
            before the built-in ones (after a lens.toml's own `glass_catalogs`; the command's
            `--glass-catalog` ones after these).
        afocal_ok: accept an afocal system (for `inspect`); otherwise it is an InputError.
        clip_edge_mm: the gap kept between crossing faces where an element is edged inside the beam
            (design.edges.clip_gap: the default mount's least edge when None).
        max_clip_vignetting: the largest share of a field's pupil such clips may stop before the lens
            is refused (any on-axis ray refused too); None: the glass decides, whatever they cost.
        clip_thin: also edge there an element whose faces come closer than that gap inside the beam.
        placed_ok: accept a lens whose surfaces do not share one axis (for `inspect`), as read: its
            semi-diameters stay the file's, since the beam heights come from the coaxial trace; the
            mount, the scene and the tracer refuse it here.
    """
    path = _resolve(Path(path))
    file = str(path)
    glass_catalogs = (*glass_catalogs, *_command_catalogs)
    if path.suffix.lower() == ".zmx":
        prescription, file_margin = read_zmx(path, glass_catalogs), 0.0
    else:
        prescription, file_margin = read_lens_toml(path, glass_catalogs)
    margin = file_margin if margin_mm is None else margin_mm
    try:
        validate(prescription, file, afocal_ok)
        if prescription.frames:
            if not placed_ok:
                require_coaxial(prescription, "the mount, the stray-light scene and the tracer")
            return prescription, ()
        complete, clips = clip_crossing_elements(prescription, margin, file, clip_edge_mm, max_clip_vignetting,
                                                 clip_thin)
        _check_radii(complete, file, given_only=False)
        _check_crossings(complete, file, given=[s.clear_semi_diameter is not None for s in prescription.surfaces])
        _check_image(complete, file, afocal_ok)
    except InputError as exc:
        raise _located(exc, path) from None
    return (complete, clips) if auto_clear_apertures else (prescription, ())


def import_notes(path, glass_catalogs=()) -> list:
    """What reading a .zmx imported, substituted and ignored (ImportNote rows); for lens.toml, the
    glasses found elsewhere than under their name in a built-in catalogue."""
    path = _resolve(Path(path))
    glass_catalogs = (*glass_catalogs, *_command_catalogs)
    if path.suffix.lower() != ".zmx":
        return _glass_notes(read_lens_toml(path, glass_catalogs)[0])
    return read_zmx_with_notes(path, glass_catalogs)[1]


def _glass_notes(p: Prescription) -> list:
    notes = []
    for i, s in enumerate(p.surfaces):
        found = resolve_glass(s.material) if s.material.upper() != AIR and not MODEL_GLASS.match(s.material) else None
        if found is not None and (found.substituted or found.step.startswith("user")):
            notes.append(ImportNote("substituted" if found.substituted else "imported", f"surface {i + 1}",
                                    f"glass {s.material}" + (f" -> {found.material}" if found.substituted else "")
                                    + f" ({found.step})"))
    return notes


def save_lens_toml(prescription: Prescription, path, margin_mm: float = 0.0, header: str | None = None) -> Path:
    """Write the prescription as lens.toml (atomically)."""
    return write_lens_toml(prescription, path, margin_mm, header)


def validate(prescription: Prescription, file: str = "lens", afocal_ok: bool = False) -> None:
    """Checks that need no ray trace. Raises InputError. afocal_ok: accept an afocal system
    (`inspect` shows one; the mount and the tracer need an image). Whether the lens forms a real
    image at all is checked after the real rays (load_lens_and_clips), which name a surface the beam
    misses first; here only where the image plane lies in front of surface 1."""
    p = prescription
    if not all(0.1 <= w <= 20.0 for w in p.wavelengths_um):
        raise InputError(f"wavelengths {list(p.wavelengths_um)} µm include one outside 0.1-20 µm", file=file,
                         field="wavelengths.values_um", valid="wavelengths in µm between 0.1 and 20")
    if not all(abs(f) < 89.0 for f in p.field_angles_deg):
        raise InputError(f"field angles {list(p.field_angles_deg)} include one of 89° or more", file=file,
                         field="field.angles_deg", valid="field angles strictly between -89 and 89 degrees")
    if not (p.aperture.value > 0 and math.isfinite(p.aperture.value)):
        raise InputError(f"aperture value {p.aperture.value} is not a positive number", file=file,
                         field="aperture", valid="an f-number or entrance pupil diameter > 0")
    stops = [i for i, s in enumerate(p.surfaces) if s.is_stop]
    if not stops:
        raise InputError("no surface is marked as the aperture stop", file=file, field="surface[].stop",
                         valid="exactly one surface with stop = true (Zemax: a STOP line)")
    if len(stops) > 1:
        raise InputError(f"surfaces {', '.join(str(i + 1) for i in stops)} are all marked as the stop",
                         file=file, field=f"surface[{stops[1] + 1}].stop", valid="exactly one stop surface")
    for i, s in enumerate(p.surfaces):
        try:
            n = refractive_index(s.material, np.asarray(p.wavelengths_um))
        except InputError as exc:
            raise InputError(exc.detail, file=file, field=f"surface[{i + 1}].material", valid=exc.valid) from None
        if not np.all(np.isfinite(n)) or np.any(n < 1.0):
            raise InputError(f"material '{s.material}' has no valid index over the wavelengths "
                             f"{', '.join(f'{w:g}' for w in p.wavelengths_um)} µm", file=file,
                             field=f"surface[{i + 1}].material", valid="a glass whose catalogue covers these wavelengths")
        if p.holds_glass_after(i) and s.thickness * p.travel[i] <= 0:
            raise InputError(f"glass thickness {s.thickness:g} mm after surface {i + 1} runs against the light",
                             file=file, field=f"surface[{i + 1}].thickness",
                             valid="a centre thickness > 0 mm for a glass (< 0 after an odd number of mirrors); "
                                   "negative thickness only in air")
        if s.clear_semi_diameter is not None and s.mechanical_semi_diameter is not None \
                and s.mechanical_semi_diameter < s.clear_semi_diameter:
            raise InputError(f"mechanical semi-diameter {s.mechanical_semi_diameter:g} mm is smaller than the clear "
                             f"semi-diameter {s.clear_semi_diameter:g} mm", file=file,
                             field=f"surface[{i + 1}].mechanical_semi_diameter",
                             valid="mechanical semi-diameter >= clear semi-diameter")
    face = p.immersion_face
    if face is not None and (p.image_z - p.vertex_z[face]) * p.travel[-1] < 0:
        raise InputError(
            f"the image plane lies {abs(p.image_z - p.vertex_z[face]):g} mm before surface {face + 1}, against the "
            f"light, inside {p.image_medium}, the medium after that face: the beam has come to its focus in front of "
            "the face and diverges in the medium, so the image the file puts there is virtual (an image solve that "
            "found the focus before the last face) and no detector or specimen can sit in it; a cover glass "
            "whose back face the file dropped has no thickness to build", file=file,
            field=f"surface[{len(p.surfaces)}].thickness",
            valid=f"an image space after surface {face + 1}: the image plane behind it in its medium (a real "
                  "image), or the focus in the air in front of the face with the face removed")
    if p.image_z <= 0 and not p.has_mirrors:
        _check_image(p, file, afocal_ok)   # the reason, when it is one: no real image (a negative lens), afocal
        raise InputError("the image plane lies in front of surface 1", file=file,
                         field=f"surface[{len(p.surfaces)}].thickness", valid="a total track > 0 mm")
    _check_radii(p, file, given_only=True)


def _check_image(p: Prescription, file: str, afocal_ok: bool) -> None:
    """lensmount traces to a detector at a real image: an afocal system (optics.paraxial) has no image
    at a finite distance, and a lens whose paraxial image lies before its last surface (a diverging
    lens, or an object inside the focal length) forms only a virtual one."""
    par = paraxial(p)
    last = f"surface[{len(p.surfaces)}].thickness"
    if par.afocal:
        if afocal_ok:
            return
        raise InputError(
            f"the lens is afocal (angular magnification {par.angular_magnification:.4g}x: its power is below "
            f"{AFOCAL_POWER_RATIO:g} of its surfaces' powers), so it forms no image at a finite distance for a "
            "detector to sit in; lensmount's mount, scene and tracer are built around a focused image",
            file=file, field=last,
            valid="a focusing lens; for an afocal system, add the camera lens (or an ideal lens of a stated "
                  "focal length) behind it in the file")
    if par.bfl * p.travel[-1] <= 0:
        which = "object" if p.finite_object else "object at infinity"
        raise InputError(
            f"the lens forms no real image: the paraxial image of the {which} lies {abs(par.bfl):.4g} mm before "
            f"the last surface (a virtual image; effective focal length {par.efl:.4g} mm), so there is no image "
            "for a detector to sit in", file=file, field=last,
            valid="a lens that forms a real image (positive power for an object at infinity, or an object "
                  "beyond the front focal point)")


def _outer_semi_diameter(s) -> float | None:
    return s.mechanical_semi_diameter if s.mechanical_semi_diameter is not None else s.clear_semi_diameter


def _check_radii(p: Prescription, file: str, given_only: bool) -> None:
    """|radius| (more exactly: the conic's reach) must cover the semi-diameter."""
    for i, s in enumerate(p.surfaces):
        h = _outer_semi_diameter(s)
        if h is None:
            continue
        reach = Profile.of(s).max_radius()
        if h > reach * (1.0 + 1e-12):
            which = "clear" if s.mechanical_semi_diameter is None else "mechanical"
            src = "given" if given_only else "needed by the beam"
            if s.conic == 0.0 and s.qtype is None:
                raise InputError(
                    f"radius {s.radius:g} mm of surface {i + 1} is smaller than its {which} semi-diameter "
                    f"{h:.4g} mm ({src})", file=file, field=f"surface[{i + 1}].radius",
                    valid=f"|radius| >= {h:.4g} mm for this semi-diameter, or a smaller semi-diameter")
            face = "Q-type face" if s.qtype is not None else "face"
            raise InputError(
                f"the {face} of surface {i + 1} (radius {s.radius:g} mm, conic {s.conic:g}) exists out to "
                f"r = {reach:.4g} mm only, less than its {which} semi-diameter {h:.4g} mm ({src})", file=file,
                field=f"surface[{i + 1}].radius",
                valid=f"a radius and conic whose surface reaches {h:.4g} mm, or a smaller semi-diameter")


def _dummy_in_air(p: Prescription, i: int) -> bool:
    """Surface i only marks a plane: air on both sides, neither the stop (the diaphragm) nor a mirror."""
    s = p.surfaces[i]
    return s.is_air_after and p.material_before(i).upper() == AIR and not s.is_stop and not s.mirror


def _check_crossings(p: Prescription, file: str, given=None) -> None:
    """Neighbouring surfaces must not cross within the semi-diameter they share.

    In glass the element's edge is where both faces reach (the larger semi-diameter,
    as long as both profiles exist there); across air the common clear zone (the
    smaller one), since what lies beyond is the mount's business. `given[i]`: surface i's
    semi-diameter is the file's (else the beam's own, which then needs the crossed zone).
    """
    for i in range(len(p.surfaces) - 1):
        a, b = p.surfaces[i], p.surfaces[i + 1]
        ha, hb = _outer_semi_diameter(a), _outer_semi_diameter(b)
        if ha is None or hb is None or (a.is_air_after and (_dummy_in_air(p, i) or _dummy_in_air(p, i + 1))):
            continue   # a reference plane in air is no part: a gap to it may be negative (OpticStudio's -1e-8 mm)
        h = max(ha, hb) if not a.is_air_after else min(ha, hb)
        h = min(h, Profile.of(a).max_radius(), Profile.of(b).max_radius())
        r = np.linspace(0.0, h, _CROSS_SAMPLES)
        gap = face_gap(p, i, r)
        k = int(np.argmin(gap))
        if gap[k] < -_CROSS_TOL:
            medium = "glass" if not a.is_air_after else "air"
            m = int(np.argmax(gap < -_CROSS_TOL))   # first sample past the meeting radius
            meet = height_at_gap(p, i, r[max(m - 1, 0)], r[m], -_CROSS_TOL)
            whose = [f"{h:.4g} mm on surface {j + 1} ("
                     + ("the file's" if given is None or given[j] else "reached by the beam of the full field "
                        "and aperture") + ")" for j, h in ((i, ha), (i + 1, hb))]
            raise InputError(
                f"surfaces {i + 1} and {i + 2} cross each other: the faces meet {meet:.4g} mm from the axis, and at {r[k]:.4g} mm surface {i + 2} lies {-gap[k]:.3g} mm in front of surface {i + 1} "
                f"({medium} gap of {a.thickness:g} mm on the axis), inside the semi-diameters {' and '.join(whose)}",
                file=file, field=f"surface[{i + 1}].thickness",
                valid=f"a thickness of at least {a.thickness - gap[k]:.4g} mm, or flatter curvatures")


def _located(exc: InputError, path: Path) -> InputError:
    """The error with the file, and for lens.toml the line of the field, filled in."""
    line = exc.line
    if line is None and exc.field and path.suffix.lower() != ".zmx":
        try:
            line = line_of_field(path.read_text(encoding="utf-8"), exc.field)
        except OSError:
            line = None
    return InputError(exc.detail, file=exc.file or str(path), field=exc.field, line=line, valid=exc.valid)


LENS_NAMES = ("lens.toml", "lens.zmx")


def find_lens(root: Path) -> Path:
    """The lens file of a design folder: exactly one of lens.toml and lens.zmx.

    Both present is an error: one would silently win over an edited other.
    """
    root = Path(root)
    found = [root / n for n in LENS_NAMES if (root / n).is_file()]
    if not found:
        raise InputError("the design folder holds no lens file", file=str(root),
                         valid="a lens.toml or lens.zmx in the folder")
    if len(found) > 1:
        raise InputError("the design folder holds both lens.toml and lens.zmx, and which one is meant is "
                         "ambiguous", file=str(root), field="lens file",
                         valid="exactly one lens file: remove or rename the other "
                               "(`lensmount inspect lens.zmx --save-toml lens.toml` converts)")
    return found[0]


def _resolve(path: Path) -> Path:
    if path.is_dir():
        return find_lens(path)
    if not path.exists():
        raise InputError("file not found", file=str(path), valid="a path to an existing lens.toml or .zmx file")
    return path


__all__ = ["load_lens", "load_lens_and_clips", "import_notes", "save_lens_toml", "validate", "find_lens", "LENS_NAMES",
           "use_command_glass_catalogs"]
