"""Assembly: the planned parts built as solids (built-in or user templates), checked,
and tessellated into one tagged mesh.

Order of work (each step is one progress tick in `lensmount regenerate`):
layout → profile checks → solids → checks on user-template parts → tessellation.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

import lensmount
from lensmount.cad.checks import check_layout
from lensmount.cad.layout import plan
from lensmount.cad.plan import Layout, PartPlan
from lensmount.mesh import TaggedMesh
from lensmount.cad.tessellate import tessellate_part
from lensmount.design.mount import MountSpec
from lensmount.cad.step_beam import beam_report
from lensmount.cad.step_parts import (StepSource, check_used, datum_z, face_finishes, file_sha256, part_names,
                                      placement, raise_sliver, read_entry, sliver_to_glass, step_part_kind)
from lensmount.errors import GeometryError, InputError
from lensmount.optics.prescription import Prescription
from lensmount.templates.profile import face_roles, unmatched_segments
from lensmount.templates.user import declared_roles, load_template, to_solid

if TYPE_CHECKING:  # build123d/OCP take seconds to load; planning and checking a layout do without them
    from build123d import Compound, Solid

USER_OVERLAP_TOL_MM3 = 1e-3


@dataclass
class BuiltPart:
    """A part ready for export: its plan, solid, face roles and content hash."""

    plan: PartPlan
    solid: Solid | Compound  # a user template's may be a compound of solids
    roles: list[tuple[str, int]]
    user_template: Path | None  # the user's file: a template, or a STEP part's file
    hash: str
    field: str = ""  # the mount.toml field that names the user's file
    face_finishes: list[str] | None = None  # a STEP part's finish per face (else plan.finish)
    face_labels: list[str] | None = None  # a STEP part's face names
    face_assigned: list[str] | None = None  # how each face's finish was given face by face ("" its part's)

    @property
    def name(self) -> str:
        return self.plan.name


def part_hash(plan: PartPlan, template_bytes: bytes | None) -> str:
    """Hash of everything a part's STEP depends on (not its neighbours)."""
    payload = {"version": lensmount.__version__, "name": plan.name, "kind": plan.kind, "finish": plan.finish,
               "template": type(plan.template).__name__, "params": plan.template.params()}
    h = hashlib.sha256(json.dumps(payload, sort_keys=True, default=_json_default).encode())
    if template_bytes is not None:
        h.update(template_bytes)
    return h.hexdigest()


def _json_default(x):
    if isinstance(x, float):
        return repr(x)
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, tuple):
        return list(x)
    raise TypeError(type(x))


def build_parts(layout: Layout, spec: MountSpec, template_paths: dict[str, Path] | None = None,
                progress=None) -> list[BuiltPart]:
    """Solids for every planned part; user templates replace the built-in ones per kind."""
    template_paths = template_paths or {}
    makers = {kind: load_template(path, kind) for kind, path in template_paths.items()}
    out = []
    for k, pp in enumerate(layout.parts):
        segs = pp.template.segments()
        path = template_paths.get(pp.kind)
        face_role = None
        if path is not None:
            make_part, face_role = makers[pp.kind]
            try:
                result = make_part(pp.name, pp.template.params())
            except Exception as exc:  # the user's code
                raise GeometryError(f"user template for {pp.name} failed: {exc!r}", file=str(path),
                                    field=f"templates.{pp.kind}", valid="make_part returning a solid") from None
            solid = to_solid(result, path, pp.kind)
            raw = path.read_bytes()
        else:
            solid = pp.template.build()
            raw = None
        if not solid.is_valid:
            raise GeometryError(f"{pp.name}: the CAD kernel built an invalid solid", field=pp.kind,
                                valid="parameters giving a simple closed profile")
        roles = face_roles(solid, segs)
        lost = [] if path is not None else unmatched_segments(roles, segs)
        if lost:   # a face left `mount` would absorb the light as metal does: refuse rather than mis-tag
            raise GeometryError(f"{pp.name}: {len(lost)} face(s) of the revolved profile were not found on the "
                                f"solid ({', '.join(f'{s.role} from r = {s.start[0]:.3f} to {s.end[0]:.3f} mm' for s in lost)})",
                                field=pp.kind, valid="a profile whose faces the CAD kernel keeps apart")
        if face_role is not None:
            roles = declared_roles(solid, face_role, pp.name, pp.template.params(), roles, path, pp.kind)
        out.append(BuiltPart(pp, solid, roles, path, part_hash(pp, raw), f"templates.{pp.kind}" if path else ""))
        if progress:
            progress("solids", k + 1, len(layout.parts))
    return out


def _common(a, b):
    """The boolean intersection of two solids (OCC), as a build123d shape."""
    from build123d import Shape  # lazy: build123d/OCP take seconds to load; only solid modelling needs them
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common

    op = BRepAlgoAPI_Common(a.wrapped, b.wrapped)
    op.Build()
    return Shape.cast(op.Shape())


def leave_out(plan: PartPlan, layout: Layout, spec: MountSpec) -> str:
    """The mount.toml setting that leaves a generated part out: what a user's part that collides with
    it (often the generated hood's vanes inside a hood the user replaced) asks the user to set."""
    vs = spec.vanes
    if plan.kind == "vane" and plan.template.z_front < datum_z("barrel-front", layout):  # in the hood
        return ("[vanes] count = 0" if vs.placement == "even" and vs.positions_mm is None
                else "[vanes] positions_mm = []") + " (no vanes in the hood)"
    settings = {"vane": "[vanes] in_air_gaps = 0 (no vanes in the spacer tubes)", "hood": "[hood] enabled = false",
                "housing": "[housing] enabled = false"}
    if plan.name == "rear-baffle":
        return "[housing] rear_baffle = false"
    return settings.get(plan.kind, f"[parts.{plan.name}] (your own part in its place)")


def check_user_parts(parts: list[BuiltPart], leave_out: dict[str, str] | None = None) -> None:
    """3D interference of user-template parts with every other part (OCC boolean common). `leave_out`:
    for a generated part, the mount.toml setting that removes it, which the error then offers."""
    for a in parts:
        if a.user_template is None:
            continue
        ba = a.solid.bounding_box()
        for b in parts:
            if b is a or (b.user_template is not None and b.name < a.name):
                continue
            bb = b.solid.bounding_box()
            if (ba.min.X > bb.max.X or bb.min.X > ba.max.X or ba.min.Y > bb.max.Y or bb.min.Y > ba.max.Y
                    or ba.min.Z > bb.max.Z or bb.min.Z > ba.max.Z):
                continue
            common = _common(a.solid, b.solid)
            vol = float(common.volume)
            if vol > USER_OVERLAP_TOL_MM3:
                box = common.bounding_box()
                depth = min(box.size.X, box.size.Y, box.size.Z)
                remove = (leave_out or {}).get(b.name) if b.user_template is None else None
                raise GeometryError(f"{a.name} and {b.name} overlap by {depth:.3f} mm ({vol:.3f} mm³)",
                                    file=str(a.user_template), field=a.field,
                                    valid="a part that stays clear of its neighbours"
                                          + (f", or the generated {b.name} left out: {remove} in mount.toml"
                                             if remove else ""))


def check_user_beam(layout: Layout, part: BuiltPart, mesh: TaggedMesh) -> None:
    """A user-template part's mesh vertices stay out of the beam (exact envelope near it)."""
    if part.plan.kind in ("lens", "diaphragm"):
        return
    v = mesh.vertices
    r, z = np.hypot(v[:, 0], v[:, 1]), v[:, 2]
    env = layout.envelope
    inside_z = (z >= env.z[0]) & (z <= env.z[-1])
    near = inside_z & (r < env.at(z) + 0.3)
    if not near.any():
        return
    into = env.exact(z[near]) - r[near]
    k = int(np.argmax(into))
    if into[k] > 1e-3:
        raise GeometryError(f"{part.name} enters the beam footprint of the full field by {into[k]:.3f} mm "
                            f"at z = {z[near][k]:.2f} mm", file=str(part.user_template),
                            field=part.field, valid="a part outside the beam envelope")


# Part meshes of this process by what they depend on: a long-lived process (`lensmount watch`, a notebook)
# tessellates again only the parts an edit changed (removing the hood's vanes leaves 15 of 17 as they were).
_PART_MESHES: dict[tuple, TaggedMesh] = {}
_PART_MESHES_KEPT = 256


def _part_mesh(bp: BuiltPart, tol) -> TaggedMesh:
    """tessellate_part of a built part, from _PART_MESHES when the part is unchanged: its content hash
    (everything its solid depends on, as for its STEP file), its face roles, finishes and labels, and the
    tolerances."""
    key = (bp.hash, tuple(bp.roles), tuple(bp.face_finishes or ()), tuple(bp.face_labels or ()),
           tuple(bp.face_assigned or ()), tol.linear_tolerance_mm, tol.angular_tolerance_deg)
    m = _PART_MESHES.get(key)
    if m is None:
        m = tessellate_part(bp.solid, bp.name, bp.plan.kind, bp.plan.finish, bp.roles,
                            tol.linear_tolerance_mm, tol.angular_tolerance_deg, finishes=bp.face_finishes,
                            labels=bp.face_labels, assigned=bp.face_assigned)
        if len(_PART_MESHES) >= _PART_MESHES_KEPT:
            _PART_MESHES.pop(next(iter(_PART_MESHES)))  # the oldest
        _PART_MESHES[key] = m
    return m


def tessellate(parts: list[BuiltPart], spec: MountSpec, layout: Layout, progress=None) -> tuple[TaggedMesh, dict]:
    """One TaggedMesh for the assembly (parts in order) and triangles per part."""
    tol = spec.tessellation
    meshes, counts = [], {}
    for k, bp in enumerate(parts):
        m = _part_mesh(bp, tol)
        if isinstance(bp.plan.template, StepSource):
            check_step_beam(layout, spec, bp, m)
        elif bp.user_template is not None:
            check_user_beam(layout, bp, m)
        meshes.append(m)
        counts[bp.name] = int(len(m.triangles))
        if progress:
            progress("tessellation", k + 1, len(parts))
    return TaggedMesh.concatenate(meshes), counts


def build_assembly(prescription: Prescription, spec: MountSpec, template_paths=None, progress=None,
                   step_paths: dict[str, Path] | None = None):
    """Layout, checks, solids: (Layout, [BuiltPart]). Raises GeometryError on a violation.

    `step_paths` (`[parts.NAME]` → its STEP file) replace the generated part NAME or add parts."""
    if progress:
        progress("layout", 0, 1)
    layout = plan(prescription, spec)
    replaced = {pp.name: pp.kind for pp in layout.parts if pp.name in (step_paths or {})}
    layout.parts = [pp for pp in layout.parts if pp.name not in replaced]
    if progress:
        progress("layout", 1, 1)
    check_layout(layout, spec, {p.name: p.template.segments() for p in layout.parts
                                if p.kind not in (template_paths or {})})
    if progress:
        progress("checks", 1, 1)
    parts = build_parts(layout, spec, template_paths, progress)
    parts += step_built_parts(layout, spec, step_paths or {}, replaced, {p.name for p in parts})
    check_user_parts(parts, {p.name: leave_out(p.plan, layout, spec) for p in parts if p.user_template is None})
    lenses = [(p.name, p.solid) for p in parts if p.plan.kind == "lens"]
    for bp in parts:
        if isinstance(bp.plan.template, StepSource):
            found = sliver_to_glass(bp.solid, lenses, spec.seats.clearance_mm)
            if found:
                raise_sliver(bp.name, found, spec.seats.clearance_mm)
    return layout, parts


def step_built_parts(layout: Layout, spec: MountSpec, step_paths: dict[str, Path], replaced: dict[str, str],
                     taken: set[str]) -> list[BuiltPart]:
    """The `[parts.NAME]` entries read, placed and finished face by face (cad.step_parts)."""
    out = []
    for name, path in step_paths.items():
        entry = spec.parts[name]
        step = read_entry(spec, name, path)
        try:
            z0 = datum_z(entry.datum, layout)
        except InputError as exc:
            raise InputError(exc.detail, field=f"parts.{name}.datum", valid=exc.valid) from None
        where = placement(entry, z0)
        digest = file_sha256(path)
        kind = step_part_kind(entry, replaced.get(name))
        used: dict[str, set] = {}
        for part, solid in zip(part_names(name, step, taken | set(step_paths)), step.solids):
            placed = solid.solid.moved(where)
            default = spec.finish_of(part, entry.finish)
            finishes = face_finishes(entry, part, solid, placed, used, default)
            pp = PartPlan(part, kind, default, StepSource(path, digest, name, entry, solid.name, z0))
            faces = len(finishes.finishes)
            out.append(BuiltPart(pp, placed, [("mount", -1)] * faces, path, part_hash(pp, None),
                                 f"parts.{name}.step", finishes.finishes, list(solid.face_names),
                                 [why if why != "default" else "" for why in finishes.sources]))
            layout.notes.append(f"{part}: from {path.name} ({step.unit}), {faces} faces: "
                                + _finish_summary(finishes))
        layout.notes += check_used(entry, name, used, step)
    return out


def _finish_summary(finishes) -> str:
    count: dict[tuple[str, str], int] = {}
    for f, why in zip(finishes.finishes, finishes.sources):
        key = (f, why.split(" ")[0] if why != "default" else why)
        count[key] = count.get(key, 0) + 1
    return ", ".join(f"{n} {f} (by {why})" for (f, why), n in sorted(count.items()))


def check_step_beam(layout: Layout, spec: MountSpec, part: BuiltPart, mesh: TaggedMesh) -> None:
    """A STEP part clears the beam envelope by its margin and vignettes no field, or regenerate stops
    (GeometryError, exit 2) unless its entry allows it; either way the figures go into the notes."""
    name, entry = part.plan.template.entry_name, part.plan.template.entry
    margin = entry.beam_margin_mm if entry.beam_margin_mm is not None else spec.vanes.aperture_margin_mm
    report = beam_report(layout, mesh)
    unit = " mm" if layout.prescription.finite_object else "°"
    r, z = report.at
    if not math.isfinite(report.clearance):
        clear = "lies outside the beam's z range"
    else:
        clear = (f"clears the beam envelope by {report.clearance:.3f} mm" if report.clearance >= 0
                 else f"cuts into the beam envelope by {-report.clearance:.3f} mm") + f" at r = {r:.2f} mm, z = {z:.2f} mm"
    text = f"{part.name}: {clear} (margin {margin} mm); vignetting {report.lines(unit)}"
    short = report.clearance < margin or report.worst.max() > 0
    if short and not entry.allow_vignetting:
        raise GeometryError(text, field=f"parts.{name}",
                            valid=f"a part at least {margin} mm outside the beam envelope, or "
                                  "allow_vignetting = true in its entry")
    if short:  # built as allowed, but a loss of signal the user must see, not a note among the others
        layout.warnings.append(f"{text} (built: [parts.{name}] allow_vignetting = true)")
    else:
        layout.notes.append(text)


__all__ = ["BuiltPart", "build_parts", "build_assembly", "tessellate", "part_hash", "check_user_parts"]
