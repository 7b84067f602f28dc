"""Zemax sequential lens files (.zmx), staged: text -> ZmxLens (parsed) -> Prescription.

Supported (everything a rotationally symmetric refractive lens with the object at
infinity needs):
    UNIT MM|CM|IN|METER         lengths are converted to mm
    SURF n / TYPE STANDARD|EVENASPH / CURV / CONI / PARM k v (EVENASPH: r^(2k) terms, k >= 2)
    DISZ (INFINITY allowed for the object) / GLAS name (or ___BLANK model glass n_d, V_d)
    DIAM v type (type 1 = fixed semi-diameter, 0 = automatic) / STOP / COAT / COMM
    ENPD v | FNUM v / WAVM i wl weight (or WAVL/WWGT) / PWAV / FTYP / YFLN, XFLN (or YFLD, XFLD)
    GCAT (preferred catalogues)
Other surface types, mirrors, finite objects, non-angle fields, floating stops and an
r^2 asphere term raise an InputError naming the line. Lines with other commands
(display, tolerancing, optimisation settings) do not change the geometry and are skipped.
Files are UTF-16 (as Zemax writes them, with a BOM) or UTF-8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from lensmount.errors import InputError
from lensmount.optics.glass import CATALOGUES, refractive_index
from lensmount.optics.prescription import AIR, Aperture, Prescription, Surface

_UNITS = {"MM": 1.0, "CM": 10.0, "IN": 25.4, "INCH": 25.4, "METER": 1000.0, "M": 1000.0}
_SUPPORTED_TYPES = ("STANDARD", "EVENASPH")
# CLAP (circular aperture) is kept out of the geometry: lensmount's clear apertures come from DIAM.


@dataclass
class ZmxSurface:
    number: int
    line: int
    type: str = "STANDARD"
    type_line: int = 0
    curvature: float = 0.0
    conic: float = 0.0
    parm: dict = field(default_factory=dict)  # k -> (value, line)
    thickness: float = 0.0
    thickness_line: int = 0
    glass: str = AIR
    glass_line: int = 0
    diam: float | None = None
    diam_fixed: bool = False
    stop: bool = False
    coating: str | None = None
    comment: str | None = None


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
    n_fields: int | None = None
    n_waves: int | None = None
    xfields: list[float] = field(default_factory=list)
    yfields: list[float] = field(default_factory=list)
    catalogues: list[str] = field(default_factory=list)


def read_text(path) -> str:
    """Decode a .zmx file: UTF-16 (BOM) or UTF-8, falling back to Latin-1."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("file not found", file=str(path), valid="a path to an existing .zmx or lens.toml") from None
    except OSError as exc:
        raise InputError(f"cannot read the file ({exc})", file=str(path), valid="a readable .zmx file") from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        return raw.decode("utf-16")
    if raw[:200].count(b"\x00") > 20:  # UTF-16 without a BOM
        return raw.decode("utf-16-le" if raw[1:2] == b"\x00" else "utf-16-be")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def parse_zmx(text: str, file: str = "lens.zmx") -> ZmxLens:
    """Parse .zmx text into ZmxLens (no physics yet)."""
    lens = ZmxLens()
    cur: ZmxSurface | None = None

    def err(msg, line, valid):
        return InputError(msg, file=file, line=line, valid=valid)

    def num(tok, line, what):
        try:
            return float(tok)
        except (TypeError, ValueError):
            raise err(f"{what} '{tok}' is not a number", line, "a decimal number") from None

    for ln, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        cmd, _, rest = line.partition(" ")
        cmd = cmd.upper()
        args = rest.split()
        if cmd == "SURF":
            cur = ZmxSurface(number=int(num(args[0] if args else "", ln, "surface number")), line=ln)
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
            lens.aperture = ("epd", num(args[0] if args else "", ln, "entrance pupil diameter"), ln)
        elif cmd == "FNUM":
            lens.aperture = ("fno", num(args[0] if args else "", ln, "f-number"), ln)
        elif cmd in ("FLOA", "OBNA", "OBJNA", "PARA", "WFNO"):
            raise err(f"aperture type {cmd} is not supported", ln,
                      "ENPD (entrance pupil diameter) or FNUM (image-space F/#)")
        elif cmd == "WAVM":
            i, wl = int(num(args[0], ln, "wavelength index")), num(args[1], ln, "wavelength")
            weight = num(args[2], ln, "wavelength weight") if len(args) > 2 else 1.0
            lens.wavelengths[i] = (wl, weight)
        elif cmd == "WAVL":
            lens.wavl = [num(a, ln, "wavelength") for a in args]
        elif cmd == "WWGT":
            lens.wwgt = [num(a, ln, "wavelength weight") for a in args]
        elif cmd == "PWAV":
            lens.primary = int(num(args[0], ln, "primary wavelength"))
        elif cmd == "FTYP":
            lens.field_type = int(num(args[0], ln, "field type"))
            if lens.field_type != 0:
                raise err(f"field type {lens.field_type} is not supported (object at infinity)", ln,
                          "FTYP 0: field angles in degrees")
            if len(args) >= 4:
                lens.n_fields = int(num(args[2], ln, "number of fields"))
                lens.n_waves = int(num(args[3], ln, "number of wavelengths"))
        elif cmd in ("YFLN", "YFLD"):
            lens.yfields = [num(a, ln, "field") for a in args]
        elif cmd in ("XFLN", "XFLD"):
            lens.xfields = [num(a, ln, "field") for a in args]
        elif cmd == "GCAT":
            lens.catalogues = [a for a in args]
        elif cmd in ("TYPE", "CURV", "CONI", "PARM", "DISZ", "GLAS", "DIAM", "STOP", "COAT", "COMM"):
            if cur is None:
                raise err(f"{cmd} before any SURF line", ln, "surface data after a 'SURF n' line")
            if cmd == "TYPE":
                cur.type, cur.type_line = (args[0].upper() if args else ""), ln
                if cur.type not in _SUPPORTED_TYPES:
                    raise err(f"surface {cur.number} has type {cur.type or '(none)'}, which lensmount does not support",
                              ln, "TYPE STANDARD or TYPE EVENASPH")
            elif cmd == "CURV":
                cur.curvature = num(args[0] if args else "", ln, "curvature")
            elif cmd == "CONI":
                cur.conic = num(args[0] if args else "", ln, "conic")
            elif cmd == "PARM":
                cur.parm[int(num(args[0], ln, "parameter index"))] = (num(args[1], ln, "parameter"), ln)
            elif cmd == "DISZ":
                tok = args[0] if args else ""
                cur.thickness = math.inf if tok.upper() in ("INFINITY", "INF") else num(tok, ln, "thickness")
                cur.thickness_line = ln
            elif cmd == "GLAS":
                cur.glass_line = ln
                name = args[0] if args else AIR
                if name.upper() == "MIRROR":
                    raise err(f"surface {cur.number} is a mirror", ln, "refractive surfaces only (no GLAS MIRROR)")
                if name.upper() == "___BLANK":
                    if len(args) < 5:
                        raise err("model glass without n_d and V_d", ln, "GLAS ___BLANK 1 0 n_d V_d ...")
                    nd, vd = num(args[3], ln, "n_d"), num(args[4], ln, "V_d")
                    name = f"{nd:.6g}/{vd:.6g}"
                cur.glass = name
            elif cmd == "DIAM":
                cur.diam = num(args[0] if args else "", ln, "semi-diameter")
                cur.diam_fixed = len(args) > 1 and args[1] == "1"
            elif cmd == "STOP":
                cur.stop = True
            elif cmd == "COAT":
                cur.coating = args[0] if args else None
            elif cmd == "COMM":
                cur.comment = rest.strip().strip('"') or None
        # every other command is a display/optimisation setting with no effect here
    return lens


def to_prescription(lens: ZmxLens, file: str = "lens.zmx") -> Prescription:
    """Convert a parsed .zmx into a Prescription (object and image surfaces dropped)."""
    if len(lens.surfaces) < 3:
        raise InputError("fewer than three SURF blocks (object, one surface, image)", file=file,
                         valid="a sequential lens: SURF 0 (object), SURF 1..N, image surface")
    obj, body, image = lens.surfaces[0], lens.surfaces[1:-1], lens.surfaces[-1]
    if not math.isinf(obj.thickness):
        raise InputError("the object is at a finite distance; lensmount models an object at infinity",
                         file=file, line=obj.thickness_line or obj.line, valid="DISZ INFINITY on SURF 0")
    if image.curvature != 0.0:
        raise InputError("the image surface is curved", file=file, line=image.line, valid="a flat image surface (CURV 0)")
    if obj.stop or image.stop:
        raise InputError("the stop is on the object or image surface", file=file,
                         line=(obj if obj.stop else image).line, valid="STOP on one of SURF 1..N-1")
    s = lens.unit
    surfaces = []
    for zs in body:
        glass = zs.glass
        if glass.upper() != AIR:
            try:
                refractive_index(glass, 0.5875618)
            except InputError as exc:
                raise InputError(exc.detail, file=file, line=zs.glass_line, valid=exc.valid) from None
            if "/" not in glass and lens.catalogues:
                glass = _prefer_catalogue(glass, lens.catalogues)
        aspheric = ()
        if zs.type == "EVENASPH" and zs.parm:
            if zs.parm.get(1, (0.0, 0))[0] != 0.0:
                raise InputError(f"surface {zs.number} has an r^2 asphere term (PARM 1)", file=file,
                                 line=zs.parm[1][1], valid="PARM 1 = 0; put the base curvature in CURV")
            kmax = max(zs.parm)
            # PARM k multiplies r^(2k); in mm the coefficient scales by unit^(1 - 2k).
            aspheric = tuple(zs.parm.get(k, (0.0, 0))[0] * s ** (1 - 2 * k) for k in range(2, kmax + 1))
            while aspheric and aspheric[-1] == 0.0:
                aspheric = aspheric[:-1]
        if not math.isfinite(zs.thickness):
            raise InputError(f"surface {zs.number} has an infinite thickness", file=file,
                             line=zs.thickness_line, valid="a finite DISZ for SURF 1..N-1")
        surfaces.append(Surface(
            radius=math.inf if zs.curvature == 0 else 1.0 / (zs.curvature / s),
            thickness=zs.thickness * s, material=glass, conic=zs.conic, aspheric=aspheric,
            clear_semi_diameter=(zs.diam * s if zs.diam_fixed and zs.diam else None),
            is_stop=zs.stop, coating=zs.coating))
    if lens.aperture is None:
        raise InputError("no system aperture", file=file, valid="ENPD (entrance pupil diameter) or FNUM (F/#)")
    kind, value, ln = lens.aperture
    if value <= 0:
        raise InputError(f"aperture value {value} is not positive", file=file, line=ln, valid="a value > 0")
    aperture = Aperture(kind, value * s if kind == "epd" else value)

    waves, weights = _wavelengths(lens)
    if not waves:
        waves, weights = [0.5875618], [1.0]
    primary = min(max(lens.primary, 1), len(waves)) - 1
    fields = _fields(lens)
    return Prescription(surfaces=tuple(surfaces), aperture=aperture, wavelengths_um=tuple(waves),
                        wavelength_weights=tuple(weights), primary_wavelength=primary,
                        field_angles_deg=tuple(fields), name=lens.name)


def _wavelengths(lens: ZmxLens):
    if lens.wavelengths:
        idx = sorted(lens.wavelengths)
        if lens.n_waves:
            idx = [i for i in idx if i <= lens.n_waves]
        return [lens.wavelengths[i][0] for i in idx], [lens.wavelengths[i][1] for i in idx]
    waves = list(lens.wavl)
    weights = list(lens.wwgt[: len(waves)]) + [1.0] * (len(waves) - len(lens.wwgt))
    return waves, weights


def _fields(lens: ZmxLens) -> list[float]:
    n = lens.n_fields or max(len(lens.yfields), len(lens.xfields), 1)
    ys = (lens.yfields + [0.0] * n)[:n]
    xs = (lens.xfields + [0.0] * n)[:n]
    # The lens is rotationally symmetric: a field (x, y) is the radial angle with
    # tan^2 = tan^2 x + tan^2 y, and only its magnitude matters.
    out = []
    for x, y in zip(xs, ys):
        t = math.hypot(math.tan(math.radians(x)), math.tan(math.radians(y)))
        out.append(round(math.degrees(math.atan(t)), 12))
    seen, fields = set(), []
    for f in out:
        if f not in seen:
            seen.add(f)
            fields.append(f)
    return fields


def _prefer_catalogue(name: str, catalogues: list[str]) -> str:
    """Keep the plain name unless a GCAT catalogue holds a different glass of that name."""
    known = [c for c in catalogues if c.lower() in (k.lower() for k in CATALOGUES)]
    if not known:
        return name
    for cat in known:
        prefixed = f"{cat.upper()}:{name}"
        try:
            n_pref = float(refractive_index(prefixed, 0.5875618))
        except InputError:
            continue
        try:
            n_plain = float(refractive_index(name, 0.5875618))
        except InputError:
            return prefixed
        return name if n_plain == n_pref else prefixed
    return name


def read_zmx(path) -> Prescription:
    """Read a .zmx file into a Prescription."""
    text = read_text(path)
    return to_prescription(parse_zmx(text, str(path)), str(path))


__all__ = ["ZmxLens", "ZmxSurface", "read_text", "parse_zmx", "to_prescription", "read_zmx"]
