"""Zemax sequential lens files (.zmx), staged: text -> ZmxLens (parsed) -> Prescription + import notes.

What a lens file holds and how it is read:
    UNIT MM|CM|IN|METER          lengths are converted to mm
    TYPE STANDARD|EVENASPH|ODDASPH  CURV / CONI / PARM k v (EVENASPH: r^(2k); ODDASPH: r^k, whose
                                 even terms r^4..r^8 are imported and whose odd terms are an error)
    TYPE XASPHERE|XOSPHERE       the extended aspheres: XDAT 1 N, XDAT 2 r0, XDAT k+2 the term on
                                 (r/r0)^(2k) (even) or (r/r0)^k (odd; even powers only, as ODDASPH)
    TYPE QED_TYPE                a Forbes Q-type asphere, Qbfs or Qcon (lensmount.optics.io.zemax_qtype)
    TYPE COORDBRK                a break that is zero, or that the next breaks undo before
                                 any optical surface, is dropped; one that leaves a mirror,
                                 lens or stop on a decentred or tilted axis is an error
    GLAS name | MIRROR | ___BLANK a b n_d V_d | 6-digit code; GLAS ... 2 k is a pickup;
                                 GLAS name 4 ... dn dv: offsets (lensmount.optics.io.zemax_glass)
    MNUM n k                     n configurations, k active: the surface data are k's, the rest ignored
    DISZ (INFINITY for an object at infinity, a number for a finite object)
    DIAM v flag / CLAP rmin rmax: a fixed semi-diameter (flag 1), a pickup of one
                                 (flag 2 k), another solve (value as written) and a CLAP are
                                 honoured and vignette, except that on a lens face with no
                                 larger MEMA a fixed one the beam passes inside (and no
                                 vignetting factors fit the beam to) is the glass's edge, the
                                 mechanical semi-diameter (`_glass_edges`: a catalogue part's
                                 diameter); an automatic one (flag 0, or a pickup of
                                 one) is only Zemax's last computed value and is recomputed from
                                 lensmount's real rays, as for surfaces without a DIAM (the
                                 stop's stays: Zemax's size of the diaphragm)
    MEMA v flag / OEMA chip      the mechanical semi-diameter, flags as DIAM's (OpticStudio 2019+
                                 writes one on every surface): fixed, pickups of fixed ones and
                                 solves are kept; an automatic one is recomputed as OpticStudio
                                 does (the element's largest clear semi-diameter plus its chip
                                 zone), or left to the mount's edge allowance where there is no
                                 chip zone (OpticStudio's value is then the clear one, no edge to
                                 hold the glass by) or a face's clear one comes from real rays.
                                 A MEMA without a flag (older files) is a given value
    GCAT NAME ...                the glass catalogues; one that is not built in is read from
                                 NAME.agf beside the file when it is there (see read_zmx_with_notes)
    VDXN/VDYN/VCXN/VCYN/VANN     vignetting factors per field: the automatic semi-diameters come
                                 from the beam they leave (Prescription.vignetting)
    ENPD | FNUM v 0 (image-space F/#) | FNUM v 1 (paraxial working F/#) | OBNA v 0 (NA) |
    OBNA v 1 (cone angle, deg) | FLOA (stop size from the stop's DIAM)
    FTYP t c ...: t = 0 angles, 1 object heights, 2 paraxial image heights, 3 real image
    heights; c = 1 telecentric object space (chief rays parallel to the axis, object NA); XFLN/YFLN (or XFLD/YFLD); WAVM (or WAVL/WWGT); PWAV; GCAT
Solves and pickups: Zemax writes the value a solve or pickup produced on the CURV,
DISZ, GLAS, CONI and DIAM lines themselves, so the written value is the one used (the
pickup is noted). Lines with other commands (display, tolerancing, merit function)
do not change the geometry and are skipped. Files are UTF-16 (as Zemax writes them,
with a BOM), UTF-8 or Latin-1.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from lensmount.errors import InputError
from lensmount.optics.apertures import beam_heights
from lensmount.optics.glass import CATALOGUES
from lensmount.optics.io.agf import register_catalogue
from lensmount.optics.io import zemax_breaks, zemax_glass
from lensmount.optics.io.zemax_file import ImportNote, read_text
from lensmount.optics.io.zemax_first_order import apply_aperture_and_fields
from lensmount.optics.io.zemax_qtype import qtype_note, qtype_of
from lensmount.optics.prescription import AIR, Aperture, Prescription, Surface

_UNITS = {"MM": 1.0, "CM": 10.0, "IN": 25.4, "INCH": 25.4, "METER": 1000.0, "M": 1000.0}
_SUPPORTED_TYPES = ("STANDARD", "EVENASPH", "ODDASPH", "XASPHERE", "XOSPHERE", "QED_TYPE", "COORDBRK")
# surface types whose refusal has a reason of its own (others: not rotationally symmetric or not supported)
_IDEAL = ("an ideal thin lens (Zemax's paraxial surface), which focuses without glass: there is no element to "
          "mount or to scatter light", "real surfaces: TYPE STANDARD, EVENASPH or ODDASPH (a real lens in place of "
          "the ideal one)")
_NOT_BUILDABLE = {
    "PARAXIAL": _IDEAL,
    "PARAX_XY": _IDEAL,
    "DGRATING": ("a diffraction grating, which sends each order in its own direction: lensmount's tracer follows "
                 "refraction and reflection only", "refracting and reflecting surfaces (TYPE STANDARD, EVENASPH, "
                 "ODDASPH)"),
}
_D_LINE = 0.5875618
_MOST = 10 ** 6  # a surface number, index or flag beyond this is a damaged file
_MOST_TERMS = 256  # PARM / XDAT indices (OpticStudio's extended asphere has up to 232 terms)


@dataclass
class ZmxSurface:
    number: int
    line: int
    type: str = "STANDARD"
    type_line: int = 0
    curvature: float = 0.0
    conic: float = 0.0
    parm: dict = field(default_factory=dict)  # k -> (value, line)
    xdat: dict = field(default_factory=dict)  # k -> (value, line): extended data (XASPHERE, XOSPHERE)
    thickness: float = 0.0
    thickness_line: int = 0
    glass: str = AIR
    glass_line: int = 0
    glass_args: tuple = ()
    mirror: bool = False
    diam: float | None = None
    diam_flag: int = 0
    diam_from: int | None = None  # DIAM ... 2 k: picked up from surface k
    clap: float | None = None
    mema: float | None = None
    mema_flag: int | None = None  # None: a file older than OpticStudio's flags (the value is a given one)
    mema_from: int | None = None  # MEMA ... 2 k: picked up from surface k
    chip_zone: float = 0.0  # OEMA: the annulus OpticStudio's automatic MEMA adds to the clear semi-diameter
    stop: bool = False
    coating: str | None = None
    comment: str | None = None
    pickups: list = field(default_factory=list)  # "curvature from surface 6", ... (values as written)
    ppar: dict = field(default_factory=dict)  # k -> (source surface, scale, offset, source parameter): PPAR
    scbd: tuple | None = None  # (values, line): the surface's own tilt/decentre data, when not all zero


@dataclass
class ZmxLens:
    name: str = "lens"
    unit: float = 1.0
    surfaces: list[ZmxSurface] = field(default_factory=list)
    aperture: tuple[str, float, int] | None = None  # kind, value, line
    wavelengths: dict = field(default_factory=dict)  # index -> (um, weight)
    wavl: list[float] = field(default_factory=list)
    wwgt: list[float] = field(default_factory=list)
    primary: int = 1
    field_type: int = 0
    field_type_line: int = 0
    telecentric: bool = False  # FTYP t 1: telecentric object space
    n_fields: int | None = None
    n_waves: int | None = None
    xfields: list[float] = field(default_factory=list)
    yfields: list[float] = field(default_factory=list)
    vignetting: dict = field(default_factory=dict)  # "VDX", "VDY", "VCX", "VCY", "VAN" -> per-field values
    catalogues: list[str] = field(default_factory=list)
    configurations: tuple[int, int] = (1, 1)  # MNUM: how many, and the active one


def parse_zmx(text: str, file: str = "lens.zmx") -> ZmxLens:
    """Parse .zmx text into ZmxLens (no physics yet)."""
    lens = ZmxLens()
    cur: ZmxSurface | None = None

    def err(msg, line, valid):
        return InputError(msg, file=file, line=line, valid=valid)

    def num(tok, line, what):
        try:
            value = float(tok)
        except (TypeError, ValueError):
            raise err(f"{what} '{tok}' is not a number", line, "a decimal number") from None
        if not math.isfinite(value):
            raise err(f"{what} '{tok}' is not a finite number", line, "a decimal number")
        return value

    def arg(args, k, line, what, default=None):
        if len(args) > k:
            return num(args[k], line, what)
        if default is None:
            raise err(f"{what} is missing", line, "a decimal number")
        return default

    def whole(args, k, line, what, default=None, most=_MOST):
        value = arg(args, k, line, what, default)
        if not (value.is_integer() and abs(value) <= most):
            raise err(f"{what} '{args[k]}' is not a whole number up to {most}", line, f"a whole number up to {most}")
        return int(value)

    for ln, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        cmd, _, rest = line.partition(" ")
        cmd = cmd.upper()
        args = rest.split()
        if cmd == "SURF":
            cur = ZmxSurface(number=whole(args, 0, ln, "surface number"), line=ln)
            lens.surfaces.append(cur)
        elif cmd == "UNIT":
            unit = args[0].upper() if args else "MM"
            if unit not in _UNITS:
                raise err(f"unknown lens unit '{unit}'", ln, "UNIT MM, CM, IN or METER")
            lens.unit = _UNITS[unit]
        elif cmd == "MODE":
            if args and args[0].upper() != "SEQ":
                raise err(f"MODE {args[0]} (non-sequential) is not supported", ln, "MODE SEQ: a sequential lens")
        elif cmd == "NAME":
            lens.name = rest.strip().strip('"') or lens.name
        elif cmd == "ENPD":
            lens.aperture = ("epd", arg(args, 0, ln, "entrance pupil diameter"), ln)
        elif cmd == "FNUM":
            working = arg(args, 1, ln, "F/# type", 0.0) == 1
            lens.aperture = ("working_fno" if working else "fno", arg(args, 0, ln, "f-number"), ln)
        elif cmd == "OBNA":
            cone = arg(args, 1, ln, "object NA type", 0.0) == 1
            lens.aperture = ("object_cone_deg" if cone else "object_na", arg(args, 0, ln, "object-space NA"), ln)
        elif cmd == "FLOA":
            lens.aperture = ("float", 0.0, ln)
        elif cmd == "WAVM":
            i, wl = whole(args, 0, ln, "wavelength index"), arg(args, 1, ln, "wavelength")
            lens.wavelengths[i] = (wl, arg(args, 2, ln, "wavelength weight", 1.0))
        elif cmd == "WAVL":
            lens.wavl = [num(a, ln, "wavelength") for a in args]
        elif cmd == "WWGT":
            lens.wwgt = [num(a, ln, "wavelength weight") for a in args]
        elif cmd == "PWAV":
            lens.primary = whole(args, 0, ln, "primary wavelength")
        elif cmd == "FTYP":
            lens.field_type, lens.field_type_line = whole(args, 0, ln, "field type"), ln
            if lens.field_type not in (0, 1, 2, 3):
                raise err(f"field type {lens.field_type} is not supported", ln,
                          "FTYP 0 (angles), 1 (object heights), 2 (paraxial image heights) or 3 (real image heights)")
            lens.telecentric = arg(args, 1, ln, "telecentric object space", 0.0) == 1
            if len(args) >= 4:
                lens.n_fields = whole(args, 2, ln, "number of fields")
                lens.n_waves = whole(args, 3, ln, "number of wavelengths")
        elif cmd in ("YFLN", "YFLD"):
            lens.yfields = [num(a, ln, "field") for a in args]
        elif cmd in ("XFLN", "XFLD"):
            lens.xfields = [num(a, ln, "field") for a in args]
        elif cmd in ("VDXN", "VDYN", "VCXN", "VCYN", "VANN"):
            lens.vignetting[cmd[:3]] = [num(a, ln, "vignetting factor") for a in args]
        elif cmd == "GCAT":
            lens.catalogues = list(args)
        elif cmd == "MNUM":  # configurations: the surface data hold the active one's values
            lens.configurations = (whole(args, 0, ln, "number of configurations"),
                                   whole(args, 1, ln, "active configuration", 1.0))
        elif cmd in ("TYPE", "CURV", "CONI", "PARM", "DISZ", "GLAS", "DIAM", "CLAP", "MEMA", "STOP", "COAT", "COMM",
                     "PZUP", "OEMA", "XDAT", "PPAR", "SCBD"):
            if cur is None:
                raise err(f"{cmd} before any SURF line", ln, "surface data after a 'SURF n' line")
            _surface_line(cur, cmd, args, rest, ln, err, num, arg, whole)
        # every other command is a display/optimisation setting with no effect here
    return lens


def _surface_line(cur: ZmxSurface, cmd, args, rest, ln, err, num, arg, whole) -> None:
    if cmd == "TYPE":
        cur.type, cur.type_line = (args[0].upper() if args else ""), ln
        if cur.type in _NOT_BUILDABLE:
            why, valid = _NOT_BUILDABLE[cur.type]
            raise err(f"surface {cur.number} has type {cur.type}: {why}", ln, valid)
        if cur.type not in _SUPPORTED_TYPES:
            raise err(f"surface {cur.number} has type {cur.type or '(none)'}, which is not rotationally "
                      "symmetric or not supported by lensmount", ln,
                      "TYPE STANDARD, EVENASPH, ODDASPH, XASPHERE, XOSPHERE, QED_TYPE, or a COORDBRK that the "
                      "next breaks undo")
    elif cmd == "CURV":
        cur.curvature = arg(args, 0, ln, "curvature")
        if len(args) > 2 and args[1] == "4":  # solve type 4: pickup from surface args[2]
            cur.pickups.append(f"curvature from surface {whole(args, 2, ln, 'pickup surface')}")
    elif cmd == "PZUP":  # thickness pickup: source surface, scale, offset
        cur.pickups.append(f"thickness from surface {whole(args, 0, ln, 'pickup surface')}")
    elif cmd == "CONI":
        cur.conic = arg(args, 0, ln, "conic")
    elif cmd == "PARM":
        cur.parm[whole(args, 0, ln, "parameter index", most=_MOST_TERMS)] = (arg(args, 1, ln, "parameter"), ln)
    elif cmd == "PPAR":   # parameter pickup: k, source surface, scale, offset, source parameter (0: k)
        k = whole(args, 0, ln, "parameter index", most=_MOST_TERMS)
        source = whole(args, 1, ln, "pickup surface")
        cur.ppar[k] = (source, arg(args, 2, ln, "pickup scale", 1.0), arg(args, 3, ln, "pickup offset", 0.0),
                       whole(args, 4, ln, "pickup parameter", 0.0, most=_MOST_TERMS))
    elif cmd == "SCBD":
        values = tuple(num(a, ln, "tilt/decentre value") for a in args[1:])
        if any(values[2:]):
            cur.scbd = (values, ln)
    elif cmd == "XDAT":
        cur.xdat[whole(args, 0, ln, "extra data index", most=_MOST_TERMS)] = (arg(args, 1, ln, "extra data"), ln)
    elif cmd == "DISZ":
        tok = args[0] if args else ""
        cur.thickness = math.inf if tok.upper() in ("INFINITY", "INF") else num(tok, ln, "thickness")
        cur.thickness_line = ln
    elif cmd == "GLAS":
        cur.glass_line = ln
        name = args[0] if args else AIR
        cur.glass_args = tuple(args[1:])
        if name.upper() == "MIRROR":
            cur.mirror = True
            name = AIR  # resolved to the medium in front when converting
        cur.glass = name
    elif cmd == "DIAM":
        cur.diam = arg(args, 0, ln, "semi-diameter")
        cur.diam_flag = whole(args, 1, ln, "semi-diameter type", 0.0)
        if cur.diam_flag == 2:
            cur.diam_from = whole(args, 2, ln, "semi-diameter pickup surface")
    elif cmd == "CLAP":
        cur.clap = arg(args, 1, ln, "circular aperture radius")
    elif cmd == "MEMA":
        cur.mema = arg(args, 0, ln, "mechanical semi-diameter")
        if len(args) > 1:
            cur.mema_flag = whole(args, 1, ln, "mechanical semi-diameter type")
            if cur.mema_flag == 2:
                cur.mema_from = whole(args, 2, ln, "mechanical semi-diameter pickup surface")
    elif cmd == "OEMA":
        cur.chip_zone = arg(args, 0, ln, "chip zone")
    elif cmd == "STOP":
        cur.stop = True
    elif cmd == "COAT":
        cur.coating = args[0] if args else None
    elif cmd == "COMM":
        cur.comment = rest.strip().strip('"') or None


def to_prescription(lens: ZmxLens, file: str = "lens.zmx") -> Prescription:
    """Convert a parsed .zmx into a Prescription (object and image surfaces dropped)."""
    return convert(lens, file)[0]


def convert(lens: ZmxLens, file: str = "lens.zmx", glass_catalogs=()) -> tuple[Prescription, list[ImportNote]]:
    """The Prescription and the notes on what was imported, substituted and ignored.
    glass_catalogs: the user's .agf files, searched first for a GLAS name."""
    if len(lens.surfaces) < 3:
        raise InputError("fewer than three SURF blocks (object, one surface, image)", file=file,
                         valid="a sequential lens: SURF 0 (object), SURF 1..N, image surface")
    notes: list[ImportNote] = []
    lens = _stop_onto_coincident_face(lens, notes)
    obj, body, image = lens.surfaces[0], lens.surfaces[1:-1], lens.surfaces[-1]
    s = lens.unit
    if obj.glass.upper() != AIR:
        raise InputError("the object sits in a glass", file=file, line=obj.glass_line,
                         valid="an object in air (no GLAS on SURF 0)")
    if image.curvature != 0.0:
        raise InputError("the image surface is curved", file=file, line=image.line,
                         valid="a flat image surface (CURV 0)")
    if obj.stop or image.stop:
        raise InputError("the stop is on the object or image surface", file=file,
                         line=(obj if obj.stop else image).line, valid="STOP on one of SURF 1..N-1")
    if lens.configurations[0] > 1:
        notes.append(ImportNote("imported", "configurations", f"configuration {lens.configurations[1]} of "
                                f"{lens.configurations[0]} (the one the file's surface data hold); the others "
                                "(MNUM, THIC, APER ... operands) are ignored"))
    object_distance = obj.thickness * s if math.isfinite(obj.thickness) else math.inf
    notes.append(ImportNote("imported", "object", "at infinity" if math.isinf(object_distance)
                            else f"at {object_distance:g} mm in front of surface 1"))

    placed = zemax_breaks.frames(lens, file, notes)
    coaxial = all(f.is_axial for f in placed.values())
    # off one axis, the automatic DIAMs stay the file's: the beam heights come from the coaxial trace
    automatic = _automatic(lens) if coaxial else set()
    user = tuple(register_catalogue(p) for p in glass_catalogs)
    for p in glass_catalogs:
        notes.append(ImportNote("imported", "glass catalogues", f"{Path(p).resolve()} (searched before the "
                                "built-in catalogues)"))
    surfaces: list[Surface] = []
    numbers: list[int] = []
    edges: dict[int, tuple[float, float | None]] = {}   # faces whose fixed DIAM may be the glass's edge
    medium = AIR
    tilt = None  # (surface number, description) of a coordinate break not yet undone
    state = [0.0, 0.0, 0.0, 0.0]  # decenter x, y, tilt x, tilt y accumulated by breaks
    for zs in body:
        if zs.type == "COORDBRK" and not coaxial:
            if surfaces:
                _add_gap(surfaces, zs.thickness * s)
            elif math.isfinite(object_distance):
                object_distance += zs.thickness * s  # a gap before surface 1 moves the object away
            dx, dy, tx, ty, tz, order = zemax_breaks.break_values(lens, zs)
            notes.append(ImportNote("imported", f"SURF {zs.number}", f"coordinate break: decentre {dx:g}, {dy:g}, tilt "
                                    f"{tx:g}°, {ty:g}°, {tz:g}° ({'decentre, then tilt x, y, z' if order == 0 else 'tilt z, y, x, then decentre'})"
                                    " -> the frames of the surfaces after it"))
            continue
        if zs.type == "COORDBRK":
            for k in range(4):
                state[k] += zs.parm.get(k + 1, (0.0, 0))[0]
            if any(abs(v) > 1e-12 for v in state):
                tilt = (zs.number, _describe_break(state))
            else:
                tilt = None
            if zs.thickness != 0.0 and tilt is not None:
                _asymmetric(file, zs, tilt, "has a thickness along the decentred or tilted axis")
            if surfaces:
                _add_gap(surfaces, zs.thickness * s)
            elif math.isfinite(object_distance):
                object_distance += zs.thickness * s  # a gap before surface 1 moves the object away
            notes.append(ImportNote("ignored", f"SURF {zs.number}", "coordinate break "
                                    + ("(zero)" if not any(zs.parm.get(k, (0.0, 0))[0] for k in range(1, 5))
                                       else "undone by a later break" if tilt is None else "(see the next break)")))
            continue
        optical = zs.mirror or zs.stop or zs.curvature != 0.0 or zs.parm or zs.xdat or _glass_name(zs) != medium.upper()
        if tilt is not None and coaxial:
            if optical or zs.thickness != 0.0:
                _asymmetric(file, zs, tilt, "is a mirror, lens surface or stop" if optical else
                            "has a thickness along the decentred or tilted axis")
            notes.append(ImportNote("ignored", f"SURF {zs.number}", "dummy surface between coordinate breaks"))
            continue
        material, note = zemax_glass.material(zs, medium, lens.catalogues, user, file)
        if note:
            notes.append(ImportNote(note[0], f"SURF {zs.number}", note[1]))
        if zs.mirror:
            notes.append(ImportNote("imported", f"SURF {zs.number}", "mirror (GLAS MIRROR)"))
        if zs.pickups:
            notes.append(ImportNote("imported", f"SURF {zs.number}",
                                    "pickups: " + ", ".join(zs.pickups) + " (the values the file holds)"))
        if not math.isfinite(zs.thickness):
            raise InputError(f"surface {zs.number} has an infinite thickness", file=file,
                             line=zs.thickness_line, valid="a finite DISZ for SURF 1..N-1")
        clear, mech = _semi_diameters(lens, zs, s, notes, automatic, len(surfaces))
        if coaxial and _bounds_glass(lens, zs) and not zs.mirror and (material.upper() != AIR or medium.upper() != AIR):
            edges[len(surfaces)] = (zs.diam * s, zs.clap * s if zs.clap else None)
        qtype = qtype_of(zs, s, file)
        if qtype is not None:
            notes.append(ImportNote("imported", f"SURF {zs.number}", qtype_note(qtype, max(clear or 0.0, mech or 0.0))))
        if zs.coating:  # a name in the vendor's COATING.DAT, which the .zmx does not carry
            notes.append(ImportNote("ignored", f"SURF {zs.number}", f"coating {zs.coating} (defined in a "
                                    "coating file the lens file does not carry): the scene's coatings apply"))
        surfaces.append(Surface(
            radius=math.inf if zs.curvature == 0 else 1.0 / (zs.curvature / s),
            thickness=zs.thickness * s, material=material, conic=zs.conic, aspheric=_aspheric(zs, s, file),
            clear_semi_diameter=clear, mechanical_semi_diameter=mech, is_stop=zs.stop,
            mirror=zs.mirror, qtype=qtype))
        numbers.append(zs.number)
        medium = material
    if tilt is not None and coaxial:
        _asymmetric(file, image, tilt, "is the image surface")
    if not surfaces:
        raise InputError("no optical surface between the object and the image", file=file,
                         valid="a sequential lens: SURF 0 (object), SURF 1..N, image surface")
    surfaces = _automatic_mechanical(surfaces, [z for z in body if z.number in numbers], notes, s, edges)
    waves, weights = _wavelengths(lens)
    if not waves:
        waves, weights = [_D_LINE], [1.0]
    primary = min(max(lens.primary, 1), len(waves)) - 1
    if lens.telecentric:
        _check_telecentric(lens, object_distance, file)
        notes.append(ImportNote("imported", "fields", "telecentric object space: chief rays parallel to the axis"))
    base = Prescription(surfaces=tuple(surfaces), aperture=Aperture("epd", 1.0), wavelengths_um=tuple(waves),
                        wavelength_weights=tuple(weights), primary_wavelength=primary,
                        name=lens.name, object_distance=object_distance, object_telecentric=lens.telecentric,
                        glass_catalogs=tuple(str(Path(p).resolve()) for p in glass_catalogs),
                        frames=() if coaxial else tuple(placed[n] for n in (*numbers, image.number)))
    return _glass_edges(apply_aperture_and_fields(base, lens, numbers, notes, file), edges, numbers, notes), notes


_COINCIDENT_MM = 1e-5   # closer than this, two planes are one: OpticStudio's solves leave gaps of 1e-8 .. 1e-6 mm


def _stop_onto_coincident_face(lens: ZmxLens, notes) -> ZmxLens:
    """A stop plane in air (with dummy planes beside it) a rounding error in front of a plane lens face is
    that face's stop: OpticStudio writes such gaps (-1.09e-8 and 5.9e-7 mm in the OptoSigma objective)
    when a solve has put the stop on the glass. Kept apart, the mount would have to fit a diaphragm into
    an air gap of no length; merged, the stop is the face (a catalogue lens's stop on its front face).
    The planes are dropped, their gaps added to the gap in front of them, their STOP moved to the face."""
    if lens.aperture is not None and lens.aperture[0] == "float":
        return lens   # the stop's own DIAM is the aperture (FLOA): it stays where it is
    out, run = list(lens.surfaces), []
    k = 1
    while k < len(out) - 1:
        zs = out[k]
        prev_glass = _glass_name(out[k - 1]) if k > 1 else AIR
        plane_in_air = (zs.type == "STANDARD" and zs.curvature == 0.0 and not zs.parm and not zs.xdat and
                        not zs.mirror and zs.clap is None and _glass_name(zs) == AIR and prev_glass == AIR)
        if plane_in_air and abs(zs.thickness) < _COINCIDENT_MM and k + 1 < len(out) - 1:
            run.append(k)
            k += 1
            continue
        face = out[k]
        if run and any(out[j].stop for j in run) and face.type == "STANDARD" and face.curvature == 0.0 \
                and not face.parm and _glass_name(face) != AIR and abs(sum(out[j].thickness for j in run)) < _COINCIDENT_MM:
            gap = sum(out[j].thickness for j in run)
            before = out[run[0] - 1]
            out[run[0] - 1] = replace(before, thickness=before.thickness + gap)
            out[k] = replace(face, stop=True)
            notes.append(ImportNote("substituted", "SURF " + ", ".join(str(out[j].number) for j in run),
                                    f"stop plane {gap:.3g} mm in front of the plane face of SURF {face.number}: "
                                    f"the stop is that face (the planes dropped)"))
            out = [zs for j, zs in enumerate(out) if j not in run]
            k -= len(run)
        run = []
        k += 1
    return replace(lens, surfaces=out) if len(out) != len(lens.surfaces) else lens


def _check_telecentric(lens: ZmxLens, object_distance: float, file) -> None:
    """Zemax allows telecentric object space only for a finite object whose aperture is an object-space
    NA or cone angle (an entrance pupil at infinity has no diameter or F/# to give)."""
    if math.isinf(object_distance):
        raise InputError("telecentric object space with the object at infinity", file=file,
                         line=lens.field_type_line, valid="a finite DISZ on SURF 0, or FTYP t 0 (not telecentric)")
    if lens.aperture is None or lens.aperture[0] not in ("object_na", "object_cone_deg"):
        raise InputError("telecentric object space needs the aperture as an object-space NA or cone angle",
                         file=file, line=lens.aperture[2] if lens.aperture else lens.field_type_line,
                         valid="OBNA v 0 (NA) or OBNA v 1 (cone angle) with FTYP t 1")


def _glass_name(zs: ZmxSurface) -> str:
    return AIR if zs.mirror else zs.glass.upper()


def _add_gap(surfaces: list[Surface], gap: float) -> None:
    if gap:
        surfaces[-1] = replace(surfaces[-1], thickness=surfaces[-1].thickness + gap)


def _describe_break(state) -> str:
    names = ("decenter x", "decenter y", "tilt about x", "tilt about y")
    units = (" (lens units)", " (lens units)", "°", "°")
    return ", ".join(f"{n} {v:g}{u}" for n, v, u in zip(names, state, units) if abs(v) > 1e-12)


def _asymmetric(file, zs: ZmxSurface, tilt, why: str):
    number, what = tilt
    raise InputError(
        f"surface {zs.number} {why} while the coordinate break at surface {number} leaves the axis "
        f"moved ({what}): the system is not rotationally symmetric about one axis (an off-axis or "
        "folded design), which lensmount's mount and tracer need",
        file=file, line=zs.type_line or zs.line,
        valid="coordinate breaks that are zero, or that later breaks undo before the next optical surface")


def _automatic(lens: ZmxLens) -> set[int]:
    """Numbers of the surfaces whose DIAM is Zemax's automatic one (flag 0, or a pickup of one).

    An automatic value is only what Zemax last computed for the beam of its own settings, not an
    aperture the designer set, so lensmount recomputes it from its real rays (lensmount.optics.
    apertures). The stop's is the exception: it is the size Zemax gives the diaphragm for the system
    aperture with its own ray aiming (US 583,336: 4.215 mm, the real on-axis ray at EPD/2, where the
    paraxial rule says 4.251 mm), and with FLOA it is the aperture: it stays."""
    return {zs.number for zs in lens.surfaces if zs.diam and _is_automatic(lens, zs, "diam") and not zs.stop}


def _is_automatic(lens: ZmxLens, zs: ZmxSurface, which: str) -> bool:
    """The DIAM ("diam") or MEMA ("mema") of `zs` is OpticStudio's automatic value: flag 0, or a
    pickup (flag 2 k) of an automatic one. A MEMA without a flag (files older than OpticStudio's
    flags on it) is a given value."""
    by_number = {z.number: z for z in lens.surfaces}
    seen = set()
    while True:
        flag, source = getattr(zs, f"{which}_flag"), getattr(zs, f"{which}_from")
        if flag == 2 and source in by_number and source not in seen:
            seen.add(zs.number)
            zs = by_number[source]
            continue
        return flag == 0


def _semi_diameters(lens: ZmxLens, zs: ZmxSurface, s: float, notes, automatic: set[int], index: int):
    """(clear, mechanical) semi-diameters in mm; a mechanical one the import recomputes is
    `_AUTOMATIC_MECHANICAL` (filled in by `_automatic_mechanical` once the elements are known)."""
    where = f"SURF {zs.number}"
    clear = zs.diam * s if zs.diam else None
    if zs.number in automatic:
        notes.append(ImportNote("substituted", where, f"semi-diameter {clear:.4g} mm, automatic in the file (what "
                                "Zemax last computed, not an aperture) -> recomputed from real rays of the "
                                "file's fields and aperture", surface=index, file_value_mm=clear))
        clear = None
    elif clear is not None:
        kind = {0: "automatic, the stop's: the diaphragm's size", 1: "fixed",
                2: f"picked up from surface {zs.diam_from}"}.get(zs.diam_flag, "solve (value as written)")
        notes.append(ImportNote("imported", where, f"semi-diameter {clear:.4g} mm, {kind}"))
    if zs.clap:
        r = zs.clap * s
        clear = r if clear is None else min(clear, r)
        notes.append(ImportNote("imported", where, f"circular aperture {r:.4g} mm"))
    if not zs.mema:
        return clear, None
    mech = zs.mema * s
    if _is_automatic(lens, zs, "mema"):
        return clear, _AUTOMATIC_MECHANICAL
    kind = {1: "fixed", 2: f"picked up from surface {zs.mema_from}", None: "given"}.get(
        zs.mema_flag, "solve (value as written)")
    if clear is not None and mech < clear:
        notes.append(ImportNote("ignored", where, f"mechanical semi-diameter {mech:.4g} mm, {kind} "
                                "(smaller than the clear one)"))
        return clear, None
    notes.append(ImportNote("imported", where, f"mechanical semi-diameter {mech:.4g} mm, {kind}"))
    return clear, mech


_AUTOMATIC_MECHANICAL = -1.0


def _automatic_mechanical(surfaces: list[Surface], body: list[ZmxSurface], notes, s: float, edges) -> list[Surface]:
    """Automatic MEMAs recomputed as OpticStudio computes them: the largest clear semi-diameter plus
    chip zone (OEMA) over the element's faces. With no chip zone that is the clear semi-diameter
    itself, which leaves no edge to hold the glass by; and where a face's clear semi-diameter is
    left to real rays the sum is not known here: both are left to the mount's edge allowance. On a
    face whose DIAM is fixed (`edges`) it is that DIAM, and `_glass_edges` says what it is."""
    zmx = {i: zs for i, zs in enumerate(body)}
    out = list(surfaces)
    p = Prescription(surfaces=tuple(surfaces), aperture=Aperture("epd", 1.0))
    groups = {i: g for g in p.lens_groups() for i in g}
    for i, surf in enumerate(surfaces):
        if surf.mechanical_semi_diameter != _AUTOMATIC_MECHANICAL:
            continue
        faces = groups.get(i, (i,))
        chips = [zmx[j].chip_zone * s for j in faces]
        clears = [surfaces[j].clear_semi_diameter for j in faces]
        where, was = f"SURF {zmx[i].number}", zmx[i].mema * s
        if any(chips) and all(c is not None for c in clears):
            mech = max(c + z for c, z in zip(clears, chips))
            what = f"{mech:.4g} mm, the element's largest clear semi-diameter plus its chip zone (OEMA)"
        else:
            mech = None
            what = ("left to the mount's edge allowance (no chip zone: OpticStudio's rule gives the clear "
                    "semi-diameter, no edge to hold the glass by)" if not any(chips) else
                    "left to the mount's edge allowance (a face's clear semi-diameter is recomputed from real rays)")
        out[i] = replace(surf, mechanical_semi_diameter=mech)
        if i not in edges:
            notes.append(ImportNote("substituted", where, f"mechanical semi-diameter {was:.4g} mm, automatic in the "
                                    f"file (what OpticStudio last computed) -> {what}"))
    return out


def _bounds_glass(lens: ZmxLens, zs: ZmxSurface) -> bool:
    """The DIAM is fixed (not OpticStudio's automatic value) and no MEMA is larger: none, an automatic
    one without a chip zone (OpticStudio's is then the element's largest DIAM), or a smaller one.
    OpticStudio draws the element's glass out to such a DIAM."""
    if not zs.diam or _is_automatic(lens, zs, "diam"):
        return False
    if not zs.mema:
        return True
    if _is_automatic(lens, zs, "mema"):
        return not zs.chip_zone
    return zs.mema <= zs.diam


def _glass_edges(p: Prescription, edges: dict[int, tuple[float, float | None]], numbers: list[int],
                 notes) -> Prescription:
    """Fixed DIAMs with no larger MEMA (`_bounds_glass`), read as what they are. OpticStudio's DIAM is
    the face's semi-diameter and its MEMA the glass's outer one, automatic = the element's largest
    DIAM plus its chip zone; semi-diameters do not vignette there (apertures do). So a fixed DIAM with
    no larger MEMA is where the glass ends, the diameter a catalogue part is sold at (Thorlabs writes
    12.7 mm on its 25.4 mm achromats, whose beam fills 11.43 mm). Per element: when the designed beam
    (real rays, the DIAMs not clipping) passes inside each such DIAM, the element's mechanical
    semi-diameter is the largest of them and the clear semi-diameters are what the beam needs there,
    as for automatic DIAMs. A DIAM the beam overfills is an aperture the design vignettes with (a
    patent's camera lens, US 8,427,765), and so are the DIAMs of a file with vignetting factors
    (OpticStudio's Set Vignetting fits them to the semi-diameters, so that the marginal rays just pass:
    US 583,336): they stay the clear semi-diameters and clip, and the glass extends past them by the
    mount's edge allowance."""
    if not edges:
        return p
    fitted = any(any(v) for v in p.vignetting)   # the beam was fitted to the DIAMs
    clear = {i: clap for i, (_, clap) in edges.items()}   # a CLAP stays an aperture
    trial = p.with_surfaces([replace(s, clear_semi_diameter=clear[i]) if i in edges else s
                             for i, s in enumerate(p.surfaces)])
    heights, missed = beam_heights(trial) if not fitted else (np.zeros(len(p.surfaces)), None)
    surfaces = list(p.surfaces)
    for group in p.lens_groups():
        faces = [i for i in group if i in edges]
        if not faces:
            continue
        edge = max([edges[i][0] for i in faces] + [p.surfaces[i].mechanical_semi_diameter or 0.0 for i in group])
        need = max(float(heights[i]) for i in group)
        where = f"SURF {numbers[group[0]]}-{numbers[group[-1]]}"
        fixed = ", ".join(f"{edges[i][0]:.4g}" for i in faces)
        if not fitted and missed is None and all(heights[i] <= edges[i][0] * (1.0 + 1e-9) for i in faces) \
                and need <= edge * (1.0 + 1e-9):
            for i in group:
                surfaces[i] = replace(surfaces[i], mechanical_semi_diameter=edge,
                                      clear_semi_diameter=clear[i] if i in edges else surfaces[i].clear_semi_diameter)
            notes.append(ImportNote("substituted", where, f"fixed semi-diameters {fixed} mm with no larger MEMA, the "
                                    f"beam inside them (it needs {need:.4g} mm): the element's glass ends there, as "
                                    f"OpticStudio draws it (a catalogue part's diameter) -> mechanical semi-diameter "
                                    f"{edge:.4g} mm, the clear ones from real rays"))
        else:
            why = "the vignetting factors fit the beam to" if fitted else "the beam overfills"
            notes.append(ImportNote("imported", where, f"fixed semi-diameters {fixed} mm with no larger MEMA, which "
                                    f"{why}: apertures the design vignettes with (they clip), the glass extends past "
                                    "them by the mount's edge allowance"))
    return p.with_surfaces(surfaces)


def _polynomial(zs: ZmxSurface, file) -> tuple[bool, dict]:
    """(even, {k: (coefficient, line)}): the surface's polynomial terms in lens units, on r^(2k) for an
    even asphere and on r^k for an odd one. The extended aspheres (XASPHERE, XOSPHERE) write their
    terms on rho = r / r0 (XDAT 1: the number of terms, XDAT 2: r0, XDAT k + 2: the k-th term), so a
    term alpha rho^p is alpha / r0^p on r^p."""
    if zs.type in ("EVENASPH", "ODDASPH"):
        return zs.type == "EVENASPH", zs.parm
    if zs.type not in ("XASPHERE", "XOSPHERE") or not zs.xdat:
        return True, {}
    count, count_line = zs.xdat.get(1, (0.0, zs.type_line))
    if not (count.is_integer() and 0 <= count <= _MOST_TERMS - 2):
        raise InputError(f"surface {zs.number} ({zs.type}) has {count:g} terms", file=file, line=count_line,
                         valid=f"XDAT 1: the extended asphere's number of terms, a whole number from 0 to "
                               f"{_MOST_TERMS - 2}")
    count = int(count)
    r0, line = zs.xdat.get(2, (0.0, zs.type_line))
    if not r0 > 0.0:
        raise InputError(f"surface {zs.number} ({zs.type}) has normalisation radius {r0:g}", file=file, line=line,
                         valid="XDAT 2 > 0: the extended asphere's normalisation radius")
    even = zs.type == "XASPHERE"
    return even, {k: (value / r0 ** (2 * k if even else k), ln)
                  for k, (value, ln) in ((k, zs.xdat.get(k + 2, (0.0, line))) for k in range(1, count + 1))}


def _aspheric(zs: ZmxSurface, s: float, file) -> tuple[float, ...]:
    """Polynomial sag terms in mm as Surface wants them: (A4, A6, ...)."""
    even, parm = _polynomial(zs, file)
    if not parm:
        return ()
    if even:
        if parm.get(1, (0.0, 0))[0] != 0.0:
            raise InputError(f"surface {zs.number} has an r^2 asphere term", file=file,
                             line=parm[1][1], valid="no r^2 term (PARM 1 / XDAT 3 = 0); put the base curvature in CURV")
        # term k multiplies r^(2k); in mm the coefficient scales by unit^(1 - 2k).
        terms = tuple(parm.get(k, (0.0, 0))[0] * s ** (1 - 2 * k) for k in range(2, max(parm) + 1))
    else:
        # odd: term k multiplies r^k. Its even terms r^4, r^6, r^8 are an even asphere; an odd
        # term (or r^2) has no counterpart in the rotationally symmetric profile the mount and tracer use.
        for k, (value, line) in sorted(parm.items()):
            if value != 0.0 and (k % 2 == 1 or k == 2):
                raise InputError(f"surface {zs.number} is an odd asphere with an r^{k} term ({value:g})",
                                 file=file, line=line,
                                 valid="odd-asphere terms on even powers from r^4 only, or TYPE EVENASPH")
        terms = tuple(parm.get(k, (0.0, 0))[0] * s ** (1 - k) for k in range(4, max(parm) + 1, 2))
    while terms and terms[-1] == 0.0:
        terms = terms[:-1]
    return terms


def _wavelengths(lens: ZmxLens):
    if lens.wavelengths:
        idx = sorted(lens.wavelengths)
        if lens.n_waves:
            idx = [i for i in idx if i <= lens.n_waves]
        return [lens.wavelengths[i][0] for i in idx], [lens.wavelengths[i][1] for i in idx]
    waves = list(lens.wavl)
    weights = list(lens.wwgt[: len(waves)]) + [1.0] * (len(waves) - len(lens.wwgt))
    return waves, weights


def read_zmx_with_notes(path, glass_catalogs=()) -> tuple[Prescription, list[ImportNote]]:
    """Read a .zmx file: the Prescription and what was imported, substituted and ignored.
    glass_catalogs: the user's .agf files, searched first for a GLAS name; after them, the
    catalogues the file's GCAT line names that sit beside it as NAME.agf (as Zemax finds them
    in its glass folder), other than the built-in ones."""
    path = Path(path)
    lens = parse_zmx(read_text(path), str(path))
    named = {c.upper() for c in lens.catalogues} - {c.upper() for c in CATALOGUES}
    beside = sorted(p for p in path.parent.iterdir() if p.suffix.lower() == ".agf" and p.stem.upper() in named)
    return convert(lens, str(path), [*glass_catalogs, *beside])


def read_zmx(path, glass_catalogs=()) -> Prescription:
    """Read a .zmx file into a Prescription."""
    return read_zmx_with_notes(path, glass_catalogs)[0]


__all__ = ["ZmxLens", "ZmxSurface", "parse_zmx", "to_prescription", "convert",
           "read_zmx", "read_zmx_with_notes"]
