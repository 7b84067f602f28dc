"""Parts from the user's STEP files (`[parts.NAME]` in mount.toml): read, checked, placed, finished by face.

Reading goes through OCC's XDE (STEPCAFControl_Reader): the file's length unit (OCC converts to
mm and we report what the file declared), the assembly tree with each component's location, the
solids' names (TDataStd_Name), face names (STEP ADVANCED_FACE names, read with
`read.stepcaf.subshapes.name`), colours (XCAFDoc_ColorTool, face colour else the solid's) and
layers (XCAFDoc_LayerTool). An assembly's solids become several parts, keeping their names.

Face indices are the order of `solid.faces()` of the solid as read (the file's face order), the
index `FaceTag.face` keeps, the numbers `parts/NAME.faces.png` draws and a `faces = [...]` rule
names. The solid must be valid (BRepCheck) and closed: an open shell is refused with the free
edges' positions and the faces they bound.
"""

from __future__ import annotations

import ctypes
import fnmatch
import hashlib
import math
import os
import re
import sys
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from lensmount.atomic import atomic_path
from lensmount.design.mount import MountSpec, StepPart
from lensmount.errors import GeometryError, InputError
from lensmount.templates.profile import outline

if TYPE_CHECKING:  # build123d/OCP take seconds to load; only STEP parts need them
    from build123d import Solid

UNIT_NAMES = {"millimetre": "mm", "mm": "mm", "millimeter": "mm", "inch": "inch", "in": "inch"}
COLOUR_TOL = 2.5 / 255  # sRGB: a CAD program's 8-bit colour written as a real and read back


@dataclass
class StepSolid:
    """One solid of a STEP file, in the file's frame (mm), with what the file says about each face."""

    name: str
    solid: Solid
    face_names: list[str]
    face_colours: list[str | None]  # "#rrggbb" sRGB, the face's own else the solid's
    face_layers: list[list[str]]


@dataclass
class StepFile:
    path: Path
    unit: str  # as declared in the file (mm, inch, or the file's own word)
    solids: list[StepSolid]


@dataclass(frozen=True)
class StepSource:
    """What a STEP part's solid comes from: hashed into the part (a new export is a new part)."""

    path: Path
    sha256: str
    entry_name: str  # NAME of its `[parts.NAME]` entry
    entry: StepPart
    solid_name: str
    datum_z_mm: float  # where its datum is in this layout: the part moves with it, its entry unchanged

    def params(self) -> dict:
        return {"step": self.path.name, "sha256": self.sha256, "entry": self.entry_name, "solid": self.solid_name,
                "datum_z_mm": self.datum_z_mm, **self.entry.model_dump(mode="json")}


@dataclass
class FaceFinishes:
    finishes: list[str]
    sources: list[str] = field(default_factory=list)  # why each face has its finish


def _field(name: str, key: str = "step") -> str:
    return f"parts.{name}.{key}"


def _label_name(label) -> str:
    # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.TCollection import TCollection_AsciiString
    from OCP.TDataStd import TDataStd_Name

    std_name = TDataStd_Name()  # a fresh attribute per call: reusing one crashes OCP
    if label.IsAttribute(TDataStd_Name.GetID_s()) and label.FindAttribute(TDataStd_Name.GetID_s(), std_name):
        return TCollection_AsciiString(std_name.Get()).ToCString()
    return ""


def _hex(colour) -> str:
    from OCP.Quantity import Quantity_TOC_sRGB  # lazy: build123d/OCP take seconds to load; only STEP parts need them

    r, g, b = colour.Values(Quantity_TOC_sRGB)
    return "#" + "".join(f"{int(round(min(max(c, 0.0), 1.0) * 255)):02x}" for c in (r, g, b))


def file_unit(reader) -> str:
    # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.TColStd import TColStd_SequenceOfAsciiString

    lengths, angles, solid_angles = (TColStd_SequenceOfAsciiString() for _ in range(3))
    reader.FileUnits(lengths, angles, solid_angles)
    names = {lengths.Value(i).ToCString().strip().lower() for i in range(1, lengths.Length() + 1)}
    units = sorted({UNIT_NAMES.get(n, n) for n in names}) or ["mm"]
    return units[0] if len(units) == 1 else "+".join(units)


@contextmanager
def kernel_output():
    """What OCC says while the block runs, kept from the terminal and handed back: a list that holds
    the lines when the block ends (colour codes and star frames removed), for the error paragraph
    that needs them. OCC's messenger prints through a C++ stream whose buffer may empty long after
    the block, so its printers are replaced for the block by one that writes to a file; anything the
    kernel writes straight to file descriptors 1 and 2 (past Python's sys.stdout and sys.stderr)
    goes to that file too, the descriptors pointed at it for the block."""
    from OCP.Message import Message, Message_Gravity, Message_PrinterOStream  # lazy: OCP takes seconds to load

    said: list[str] = []
    messenger = Message.DefaultMessenger_s()
    printers = [messenger.Printers().Value(i) for i in range(1, messenger.Printers().Length() + 1)]
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    with tempfile.TemporaryDirectory() as folder:
        log = Path(folder) / "kernel.txt"
        direct = Path(folder) / "direct.txt"
        printer = Message_PrinterOStream(str(log), False, Message_Gravity.Message_Warning)
        printer.SetToColorize(False)
        for p in printers:
            messenger.RemovePrinter(p)
        messenger.AddPrinter(printer)
        saved = [os.dup(1), os.dup(2)]
        try:
            with open(direct, "wb") as sink:
                os.dup2(sink.fileno(), 1)
                os.dup2(sink.fileno(), 2)
                try:
                    yield said
                finally:
                    ctypes.CDLL(None).fflush(None)  # the C stdio buffers, before the descriptors go back
                    os.dup2(saved[0], 1)
                    os.dup2(saved[1], 2)
        finally:
            for fd in saved:
                os.close(fd)
            printer.Close()
            messenger.RemovePrinter(printer)
            for p in printers:
                messenger.AddPrinter(p)
        text = "\n".join(f.read_bytes().decode(errors="replace") for f in (log, direct) if f.is_file())
        said += [ln for ln in (raw.strip(" *\t") for raw in re.sub(r"\x1b\[[0-9;]*m", "", text).splitlines()) if ln]


def _kernel_said(said: list[str]) -> str:
    """The kernel's error lines as a clause of the paragraph ('' when it said none)."""
    errors = [ln.removeprefix("ERR").strip() for ln in said if "ERR" in ln or "rror" in ln]
    return f" (the STEP reader says: {'; '.join(dict.fromkeys(errors[:3]))})" if errors else ""


def read_step(path: Path, name: str) -> StepFile:
    """Every solid of the file (assembly locations applied), mm, with face names, colours, layers."""
    from build123d import Location, Shape  # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.Interface import Interface_Static
    from OCP.Quantity import Quantity_Color
    from OCP.STEPCAFControl import STEPCAFControl_Controller, STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDF import TDF_Label, TDF_LabelSequence
    from OCP.TDocStd import TDocStd_Document
    from OCP.TopLoc import TopLoc_Location
    from OCP.XCAFDoc import XCAFDoc_ColorTool, XCAFDoc_ColorType, XCAFDoc_DocumentTool

    _check_instance_names(path, name)  # OCC's reader itself crashes on some of these
    STEPCAFControl_Controller.Init_s()
    Interface_Static.SetIVal_s("read.stepcaf.subshapes.name", 1)  # STEP face names
    reader = STEPCAFControl_Reader()
    reader.SetNameMode(True)
    reader.SetColorMode(True)
    reader.SetLayerMode(True)
    with kernel_output() as said:
        status = reader.ReadFile(str(path))
    if status != IFSelect_ReturnStatus.IFSelect_RetDone:
        raise InputError("not a readable STEP file" + _kernel_said(said), file=str(path), field=_field(name),
                         valid="an ISO 10303-21 (AP203/AP214/AP242) file, whole (re-export it if it was cut short)")
    damage = _parse_failures(reader.Reader())
    if damage:  # OCC's transfer of a model with broken entities can crash the process
        raise InputError(f"the STEP file is damaged: {damage}", file=str(path), field=_field(name),
                         valid="a whole ISO 10303-21 file (export it again, or restore it from a copy)")
    unit = file_unit(reader.Reader())
    doc = TDocStd_Document(TCollection_ExtendedString("XCAF"))
    with kernel_output() as more:
        transferred = reader.Transfer(doc)
    said += more
    if not transferred:
        raise InputError("the STEP file holds no shape OCC can transfer" + _kernel_said(said), file=str(path),
                         field=_field(name), valid="a STEP file with solids (or closed shells)")
    tool = XCAFDoc_DocumentTool.ShapeTool_s(doc.Main())
    colours = XCAFDoc_DocumentTool.ColorTool_s(doc.Main())
    layer_tool = XCAFDoc_DocumentTool.LayerTool_s(doc.Main())

    layer_of = []  # (layer name, shape)
    labels = TDF_LabelSequence()
    layer_tool.GetLayerLabels(labels)
    for i in range(1, labels.Length() + 1):
        shapes = TDF_LabelSequence()
        layer_tool.GetShapesOfLayer_s(labels.Value(i), shapes)
        layer_of += [(_label_name(labels.Value(i)), tool.GetShape_s(shapes.Value(j)))
                     for j in range(1, shapes.Length() + 1)]

    def colour_of(shape) -> str | None:
        c = Quantity_Color()
        for kind in (XCAFDoc_ColorType.XCAFDoc_ColorSurf, XCAFDoc_ColorType.XCAFDoc_ColorGen):
            if colours.GetColor(shape, kind, c):
                return _hex(c)
        return None

    def label_colour(label) -> str | None:
        c = Quantity_Color()
        for kind in (XCAFDoc_ColorType.XCAFDoc_ColorSurf, XCAFDoc_ColorType.XCAFDoc_ColorGen):
            if XCAFDoc_ColorTool.GetColor_s(label, kind, c):
                return _hex(c)
        return None

    out: list[StepSolid] = []

    def leaf(label, ref, loc) -> None:
        shape = tool.GetShape_s(ref)
        sub = TDF_LabelSequence()
        tool.GetSubShapes_s(ref, sub)
        sub_names = [(tool.GetShape_s(sub.Value(j)), _label_name(sub.Value(j))) for j in range(1, sub.Length() + 1)]
        own = _label_name(ref) or _label_name(label)
        base_colour = label_colour(label) or label_colour(ref) or colour_of(shape)
        solids = closed_solids(Shape.cast(shape), path, name, own)
        for k, s in enumerate(solids):
            faces = [f.wrapped for f in s.faces()]
            out.append(StepSolid(
                own if len(solids) == 1 else f"{own or 'solid'}-{k + 1}",
                s.moved(Location(loc)) if not loc.IsIdentity() else s,
                [next((n for sh, n in sub_names if sh.IsSame(f) and n), "") for f in faces],
                [colour_of(f) or colour_of(s.wrapped) or base_colour for f in faces],
                [[ln for ln, sh in layer_of if sh.IsSame(f) or sh.IsSame(s.wrapped)] for f in faces]))

    def walk(label, loc) -> None:
        ref = TDF_Label()
        if not (tool.IsReference_s(label) and tool.GetReferredShape_s(label, ref)):
            ref = label
        here = loc.Multiplied(tool.GetLocation_s(label)) if tool.IsReference_s(label) else loc
        if tool.IsAssembly_s(ref):
            comps = TDF_LabelSequence()
            tool.GetComponents_s(ref, comps)
            for i in range(1, comps.Length() + 1):
                walk(comps.Value(i), here)
        else:
            leaf(label, ref, here)

    free = TDF_LabelSequence()
    tool.GetFreeShapes(free)
    for i in range(1, free.Length() + 1):
        walk(free.Value(i), TopLoc_Location())
    if not out:
        raise InputError("the STEP file holds no solid" + _kernel_said(said), file=str(path), field=_field(name),
                         valid="a STEP file with at least one solid (or closed shell)")
    return StepFile(path, unit, out)


_INSTANCE = re.compile(rb"^[ \t]*#(\d+)[ \t]*=", re.M)


def _check_instance_names(path: Path, name: str) -> None:
    """Each entity's instance name (#N = ...) once and within 32 bits, as ISO 10303-21 requires;
    InputError naming the first that is not (a damaged file)."""
    try:
        data = path.read_bytes()
    except OSError:
        return  # OCC's reader says what is wrong with a file it cannot open
    seen: dict[int, int] = {}
    for m in _INSTANCE.finditer(data):
        number, line = int(m.group(1)), data.count(b"\n", 0, m.start()) + 1
        if number >= 2 ** 31 or number in seen:
            why = f"defined again (first on line {seen[number]})" if number in seen else "beyond 2^31 - 1"
            raise InputError(f"the STEP file is damaged: entity #{number} on line {line} is {why}", file=str(path),
                             field=_field(name), line=line,
                             valid="a whole ISO 10303-21 file (export it again, or restore it from a copy)")
        seen[number] = line


def _parse_failures(reader) -> str:
    """What OCC's parser failed on in the file just read (syntax, wrong parameter counts, references to
    entities that are not there), first few; "" when nothing."""
    checks = reader.WS().ModelCheckList(True)
    said, count = [], 0
    checks.Start()
    while checks.More():
        check = checks.Value()
        count += check.NbFails()
        said += [check.CFail(i, True) for i in range(1, check.NbFails() + 1)][:3 - len(said)]
        checks.Next()
    return f"{count} parse failure(s): " + "; ".join(said) + (" …" if count > len(said) else "") if count else ""


def free_edges(shape) -> list[tuple[np.ndarray, list[int]]]:
    """(midpoint, indices of the faces it bounds) of every edge that bounds one face only."""
    from OCP.BRep import BRep_Tool  # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_FACE
    from OCP.TopExp import TopExp
    from OCP.TopoDS import TopoDS
    from OCP.TopTools import TopTools_IndexedDataMapOfShapeListOfShape, TopTools_IndexedMapOfShape

    faces = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, faces)
    ancestors = TopTools_IndexedDataMapOfShapeListOfShape()
    TopExp.MapShapesAndAncestors_s(shape, TopAbs_EDGE, TopAbs_FACE, ancestors)
    out = []
    for i in range(1, ancestors.Extent() + 1):
        edge = TopoDS.Edge_s(ancestors.FindKey(i))
        if BRep_Tool.Degenerated_s(edge):
            continue
        owners = {faces.FindIndex(f) - 1 for f in ancestors.FindFromIndex(i)}
        uses = ancestors.FindFromIndex(i).Size()
        if len(owners) == 1 and uses == 1:  # a seam is used twice by its one face
            c = BRepAdaptor_Curve(edge)
            p = c.Value(0.5 * (c.FirstParameter() + c.LastParameter()))
            out.append((np.array([p.X(), p.Y(), p.Z()]), sorted(owners)))
    return out


def closed_solids(shape, path: Path, name: str, solid_name: str) -> list:
    """The solids of `shape`, and its free shells made solid when closed; InputError where one is open
    (naming the free edges' positions and faces) or invalid."""
    from build123d import Solid  # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeSolid
    from OCP.BRepCheck import BRepCheck_Analyzer
    from OCP.TopAbs import TopAbs_SHELL, TopAbs_SOLID
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    solids = list(shape.solids())
    shells = []
    exp = TopExp_Explorer(shape.wrapped, TopAbs_SHELL, TopAbs_SOLID)  # shells outside any solid
    while exp.More():
        shells.append(TopoDS.Shell_s(exp.Current()))
        exp.Next()
    who = f"solid '{solid_name}'" if solid_name else "the solid"
    for item in [s.wrapped for s in solids] + shells:
        free = free_edges(item)
        if free:
            where = "; ".join(f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) mm beside face {', '.join(map(str, f))}"
                              for p, f in free[:4])
            raise InputError(f"{who} is open: {len(free)} edge(s) bound only one face, at {where}"
                             + (" …" if len(free) > 4 else "") + " (file frame, face indices as read)",
                             file=str(path), field=_field(name),
                             valid="closed solids: export the part as a solid body, or close the shell")
    for sh in shells:
        solids.append(Solid(BRepBuilderAPI_MakeSolid(sh).Solid()))
    for s in solids:
        if not BRepCheck_Analyzer(s.wrapped).IsValid():
            bad = [k for k, f in enumerate(s.faces()) if not BRepCheck_Analyzer(f.wrapped).IsValid()]
            raise InputError(f"{who} is not a valid solid (BRepCheck)"
                             + (f"; invalid faces {', '.join(map(str, bad[:10]))}" if bad else ""),
                             file=str(path), field=_field(name),
                             valid="a valid solid (repair it in the CAD program, or re-export with healing)")
    return solids


def datum_z(datum: str, layout) -> float:
    """z of a named datum on the optical axis: a surface's vertex, the image plane, the barrel's ends."""
    p = layout.prescription
    if datum == "image-plane":
        return float(p.image_z)
    if datum.startswith("surface-"):
        n = int(datum.split("-")[1])
        if n > len(p.surfaces):
            raise InputError(f"the lens has no surface {n}", field="datum",
                             valid=f"surface-1 … surface-{len(p.surfaces)}, image-plane, barrel-front, barrel-back")
        return float(p.vertex_z[n - 1])
    z = outline(layout.part("barrel").template.segments())[:, 1]
    return float(z.min() if datum == "barrel-front" else z.max())


def placement(entry: StepPart, z0: float):
    """The file frame → assembly frame: rotate about x, then y, then z, then move to the datum + offset."""
    from build123d import Location  # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.gp import gp_Ax1, gp_Dir, gp_Pnt, gp_Trsf, gp_Vec
    from OCP.TopLoc import TopLoc_Location

    total = gp_Trsf()
    for axis, deg in zip(((1, 0, 0), (0, 1, 0), (0, 0, 1)), entry.rotate_deg):
        r = gp_Trsf()
        r.SetRotation(gp_Ax1(gp_Pnt(0, 0, 0), gp_Dir(*axis)), math.radians(deg))
        total = r.Multiplied(total)
    t = gp_Trsf()
    dx, dy, dz = entry.offset_mm
    t.SetTranslation(gp_Vec(dx, dy, dz + z0))
    return Location(TopLoc_Location(t.Multiplied(total)))


def face_finishes(entry: StepPart, part: str, solid: StepSolid, placed, used: dict[str, set],
                  default: str) -> FaceFinishes:
    """Each face's finish: its STEP name (or the solid's) by `names`, its colour by `colours`, its
    layers by `layers`, then the first `rules` entry that matches, then `default` (the entry's
    `finish`, or `[finishes] PART`). `used` collects the table keys that decided a face and, under
    "selected", the rules that select one whether or not an earlier source decided it (`check_used`)."""
    colours = {k.lower(): v for k, v in entry.colours.items()}
    out = FaceFinishes([])
    for k, face in enumerate(placed.faces()):
        fname, colour, layers = solid.face_names[k], solid.face_colours[k], solid.face_layers[k]
        hit = None
        for label, what in ((fname, "face name"), (solid.name, "solid name")):
            key = next((g for g in entry.names if label and fnmatch.fnmatchcase(label, g)), None)
            if key is not None:
                hit = (entry.names[key], f"{what} '{label}'", ("names", key))
                break
        if hit is None and colour is not None:
            key = next((c for c in colours if _near(c, colour)), None)
            if key is not None:
                hit = (colours[key], f"colour {colour}", ("colours", key))
        if hit is None:
            key = next((ln for ln in layers if ln in entry.layers), None)
            if key is not None:
                hit = (entry.layers[key], f"layer '{key}'", ("layers", key))
        selected = [j for j, rule in enumerate(entry.rules) if _rule_matches(rule, part, k, face)]
        used.setdefault("selected", set()).update(selected)
        if hit is None and selected:
            hit = (entry.rules[selected[0]].finish, f"rule {selected[0] + 1}", ("rules", selected[0]))
        if hit is None:
            hit = (default, "default", None)
        out.finishes.append(hit[0])
        out.sources.append(hit[1])
        if hit[2]:
            used.setdefault(hit[2][0], set()).add(hit[2][1])
    return out


def check_used(entry: StepPart, name: str, used: dict[str, set], step: StepFile) -> list[str]:
    """InputError for a names/colours/layers key no face matched (a misspelt colour would leave the
    faces the default finish without a word), listing what the file carries, and for a `rules` entry
    that selects no face. Returns notes for the rules that select faces but decide none (an earlier
    source finished every face they select)."""
    carried = {"names": sorted({n for s in step.solids for n in s.face_names + [s.name] if n}),
               "colours": sorted({c for s in step.solids for c in s.face_colours if c}),
               "layers": sorted({ln for s in step.solids for fl in s.face_layers for ln in fl})}
    for table in ("names", "colours", "layers"):
        for key in getattr(entry, table):
            if key not in used.get(table, set()) and key.lower() not in used.get(table, set()):
                raise InputError(f"no face of {step.path.name} has the {table[:-1]} {key!r}",
                                 field=_field(name, f"{table}.{key}"),
                                 valid=f"a {table[:-1]} the file carries: " + (", ".join(carried[table]) or "(none)"))
    notes = []
    for j, rule in enumerate(entry.rules):
        if j not in used.get("selected", set()):
            raise InputError(f"rule {j + 1} of [parts.{name}] ({_criteria(rule)}) selects no face of {step.path.name}",
                             field=_field(name, f"rules.{j}"),
                             valid="criteria a face meets: its index (parts/NAME.faces.png), its outward normal "
                                   "within `within_deg`, its radial extent, the part's name")
        if j not in used.get("rules", set()):
            notes.append(f"{name}: rule {j + 1} ({_criteria(rule)}) decides no face: every face it selects is "
                         "finished by its name, colour, layer or an earlier rule")
    return notes


def _criteria(rule) -> str:
    given = {k: v for k, v in rule.model_dump(exclude_none=True).items()
             if k != "finish" and (k != "within_deg" or rule.normal is not None)}
    return ", ".join(f"{k} = {v}" for k, v in given.items()) or "every face"


def _near(a: str, b: str) -> bool:
    ca = np.array([int(a[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    cb = np.array([int(b[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    return bool(np.all(np.abs(ca - cb) <= COLOUR_TOL))


def _rule_matches(rule, part: str, index: int, face) -> bool:
    if rule.part is not None and rule.part != part:
        return False
    if rule.faces is not None and index not in rule.faces:
        return False
    if rule.r_min_mm is not None or rule.r_max_mm is not None:
        # the face's radial extent from its edges (the middle of an annulus is on the axis)
        r = [math.hypot(v.X, v.Y) for e in face.edges() for v in e.positions(np.linspace(0.0, 1.0, 17))]
        if rule.r_min_mm is not None and min(r) < rule.r_min_mm - 1e-9:
            return False
        if rule.r_max_mm is not None and max(r) > rule.r_max_mm + 1e-9:
            return False
    if rule.normal is not None:
        n = face.normal_at(0.5, 0.5)
        want = np.asarray(rule.normal, dtype=np.float64)
        cos = float(np.dot([n.X, n.Y, n.Z], want) / max(np.linalg.norm(want), 1e-300))
        if cos < math.cos(math.radians(rule.within_deg)):
            return False
    return True


def part_names(name: str, step: StepFile, taken: set[str]) -> list[str]:
    """NAME for a one-solid file; an assembly's solids keep their own names (NAME-k where a name is
    missing, repeated or taken by a generated part)."""
    if len(step.solids) == 1:
        return [name]
    out = []
    for k, s in enumerate(step.solids):
        n = "".join(ch if ch.isalnum() or ch in "-_" else "-" for ch in s.name).strip("-")
        out.append(n if n and n not in taken and n not in out else f"{name}-{k + 1}")
    return out


def file_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def step_part_kind(entry: StepPart, replaced_kind: str | None) -> str:
    return entry.kind or replaced_kind or "housing"


def read_entry(spec: MountSpec, name: str, path: Path) -> StepFile:
    """Read one `[parts.NAME]` file and check its declared unit against `unit`."""
    entry = spec.parts[name]
    step = read_step(path, name)
    if entry.unit is not None and step.unit != entry.unit:
        raise InputError(f"{path.name} declares its lengths in {step.unit}, not {entry.unit}",
                         file=str(path), field=_field(name, "unit"),
                         valid=f"unit = \"{step.unit}\" (the file's own unit is always used), or re-export the file")
    return step


def sliver_to_glass(solid, lenses, clearance: float) -> tuple[str, float, tuple] | None:
    """(lens, gap, point) where the part runs closer to a lens's glass than half the clearance without
    touching it (the generated parts' rule, cad.checks.slivers), else None."""
    # lazy: build123d/OCP take seconds to load; only STEP parts need them
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape

    box = solid.bounding_box()
    for lens_name, lens in lenses:
        lb = lens.bounding_box()
        if (box.min.X > lb.max.X + clearance or lb.min.X > box.max.X + clearance or box.min.Y > lb.max.Y + clearance
                or lb.min.Y > box.max.Y + clearance or box.min.Z > lb.max.Z + clearance
                or lb.min.Z > box.max.Z + clearance):
            continue
        d = BRepExtrema_DistShapeShape(solid.wrapped, lens.wrapped)
        if not d.IsDone():
            continue
        gap = float(d.Value())
        if 1e-6 < gap < 0.5 * clearance:
            p = d.PointOnShape1(1)
            return lens_name, gap, (p.X(), p.Y(), p.Z())
    return None


def raise_sliver(name: str, found, clearance: float) -> None:
    lens, gap, (x, y, z) = found
    raise GeometryError(f"{name} runs {gap * 1e3:.2f} µm from the glass of {lens} at ({x:.3f}, {y:.3f}, {z:.3f}) mm "
                        "without touching it: a sliver a ray leaving the glass can slip through",
                        field=_field(name, "offset_mm"),
                        valid=f"a placement that touches the glass or stays at least {clearance} mm from it "
                              "(seats.clearance_mm)")


def face_picture(mesh, title: str, path: Path) -> None:
    """parts/NAME.faces.png (`face_figure`)."""
    import matplotlib.pyplot as plt  # lazy: pyplot takes ~1 s to load; only the face picture needs it

    fig = face_figure(mesh, title)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def face_figure(mesh, title: str):
    """The part from the side (z across) and from the front (x across), each face shaded and numbered
    with its STEP face index (the numbers a `faces = [...]` rule takes). The numbers stand on a ring
    around the part, in the order of the points they mark, with a leader line to a point of their face:
    on a round part the faces' own points crowd together (every annulus has its top at the same place)."""
    import matplotlib  # lazy: pyplot takes ~1 s to load; only the face picture needs it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    v, tri, tags = mesh.vertices, mesh.triangles, mesh.tags
    fig, axes = plt.subplots(1, 2, figsize=(14, 7))
    cmap = plt.get_cmap("tab20")
    faces = sorted(set(int(t) for t in tags))
    for ax, (i, j, xlabel) in zip(axes, ((2, 1, "z (mm)"), (0, 1, "x (mm)"))):
        for t in faces:
            ax.add_collection(PolyCollection(v[tri[tags == t]][:, :, [i, j]], facecolors=cmap(t % 20),
                                             edgecolors="none", alpha=0.35))
        flat = v[:, [i, j]]
        centre = 0.5 * (flat.min(axis=0) + flat.max(axis=0))
        reach = max(float(np.linalg.norm(flat - centre, axis=1).max()), 1e-9)
        anchors = _anchors(v[tri][:, :, [i, j]].mean(axis=1), tags, faces)
        ax.set_xlim(centre[0] - 1.7 * reach, centre[0] + 1.7 * reach)
        ax.set_ylim(centre[1] - 1.7 * reach, centre[1] + 1.7 * reach)
        ax.set_aspect("equal")
        fig.canvas.draw()  # the axes' final size: how long 20 pt (a three-digit number's box, corner to corner) is in mm
        ends = ax.transData.inverted().transform([[0, 0], [20 * fig.dpi / 72, 0]])
        spacing = float(ends[1, 0] - ends[0, 0])
        for t, at, label_at in zip(faces, anchors, _ring(anchors, centre, 1.15 * reach, spacing)):
            ax.annotate(str(mesh.tag_table[t].face), at, xytext=label_at, fontsize=7, ha="center", va="center",
                        bbox={"boxstyle": "round,pad=0.15", "fc": "white", "alpha": 0.9, "lw": 0.3},
                        arrowprops={"arrowstyle": "-", "lw": 0.4, "color": "0.4"})
        ax.set_xlabel(xlabel)
        ax.set_ylabel("y (mm)")
    fig.suptitle(title)
    return fig


def _anchors(centroids: np.ndarray, tags: np.ndarray, faces: list[int]) -> np.ndarray:
    """One point per face (a triangle's centroid), each as far as can be from those chosen before: faces
    that lie on one another in the view (an annulus at the front and at the back) get apart points."""
    chosen: list[np.ndarray] = []
    for t in faces:
        own = centroids[tags == t]
        if chosen:
            gap = np.linalg.norm(own[:, None, :] - np.asarray(chosen)[None], axis=2).min(axis=1)
            chosen.append(own[int(np.argmax(gap))])
        else:
            chosen.append(own[len(own) // 2])
    return np.asarray(chosen)


def _ring(anchors: np.ndarray, centre: np.ndarray, radius: float, spacing: float) -> np.ndarray:
    """Label positions on rings around the part, evenly spread in the order of their anchors' angle
    about the centre (leader lines do not cross), each ring `spacing` apart and holding as many labels
    as fit at `spacing` along it."""
    n = len(anchors)
    angle = np.arctan2(anchors[:, 1] - centre[1], anchors[:, 0] - centre[0])
    order = np.argsort(angle)
    out = np.zeros((n, 2))
    per_ring = max(1, int(2 * np.pi * radius / spacing))
    rings = -(-n // per_ring)
    for rank, k in enumerate(order):
        r = radius + spacing * (rank % rings)
        a = angle[order[0]] + 2 * np.pi * rank / n
        out[k] = centre + r * np.array([np.cos(a), np.sin(a)])
    return out


__all__ = ["face_picture", "face_figure", "read_step", "read_entry", "StepFile", "StepSolid", "StepSource", "closed_solids",
           "free_edges", "datum_z", "placement", "face_finishes", "check_used", "part_names", "file_sha256", "step_part_kind",
           "sliver_to_glass", "raise_sliver", "FaceFinishes"]
