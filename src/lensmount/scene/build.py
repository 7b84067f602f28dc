"""`build_scene(prescription, mesh, spec) -> Scene`: join the lens, the tagged mesh and the scene file.

- analytic optical surfaces from the prescription (media per wavelength from the glass
  catalogue, coatings: scene per-surface > lens file > scene default);
- scene objects (disk, rectangle, STL/STEP mesh) appended to the mesh with their finish;
- one BSDF per face tag from the finish library and the assignment rules (a mirror's coated
  face: its `"surface:N"` finish as `physics.bsdf.mirror_finish.MirrorFinish`, the scatter on top of R);
- the source's emission disc covering the front opening, outside the assembly;
- the detector at the image plane unless the scene file moves it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.errors import InputError
from lensmount.validation import did_you_mean, located
from lensmount.optics.glass import absorption_coefficient, refractive_index
from lensmount.optics.prescription import Prescription
from lensmount.optics.profiles import Profile
from lensmount.scene import primitives
from lensmount.design.finishes import deciding_rule, finish_library, finish_of
from lensmount.optics.paraxial import paraxial
from lensmount.scene.scene import Effects, FrontOpening, OpticalSurface, Scene, faces_selected
from lensmount.physics.bsdf import make_bsdf
from lensmount.physics.bsdf.mirror_finish import MirrorFinish
from lensmount.physics.detector import Detector
from lensmount.physics.interfaces import parse_coating
from lensmount.physics.sources import SOURCES, Placement, Source, SourceParams


def optical_surfaces(prescription: Prescription, wavelengths_um: np.ndarray, coating_of=None) -> list[OpticalSurface]:
    """Analytic surfaces of a prescription; coating_of(i, lens_coating) -> Coating (default: lens file
    coating, else perfect-ar)."""
    coating_of = coating_of or (lambda i, c: parse_coating(c))
    zs = prescription.vertex_z
    travel = (1,) + prescription.travel
    out = []
    for i, s in enumerate(prescription.surfaces):
        before, after = prescription.material_before(i), s.material
        if travel[i] < 0:  # reached travelling -z (after a mirror): the medium it came from lies on the +z side
            before, after = after, before
        n_before = refractive_index(before, wavelengths_um)
        n_after = refractive_index(after, wavelengths_um)
        clear = s.clear_semi_diameter if s.clear_semi_diameter is not None else math.inf
        mech = s.mechanical_semi_diameter if s.mechanical_semi_diameter is not None else clear
        out.append(OpticalSurface(i, float(zs[i]), Profile.of(s), float(clear), np.atleast_1d(n_before),
                                  np.atleast_1d(n_after), coating_of(i, s.coating),
                                  np.atleast_1d(absorption_coefficient(before, wavelengths_um)),
                                  np.atleast_1d(absorption_coefficient(after, wavelengths_um)), float(mech), s.mirror))
    return out


def front_opening(prescription: Prescription, mesh: TaggedMesh) -> FrontOpening:
    """The front aperture light enters by: the hood mouth if there is a hood, else the front of the
    assembly; its radius covers the front ring of the mesh and surface 1's semi-diameters."""
    v = mesh.vertices
    s1 = prescription.surfaces[0]
    radii = [x for x in (s1.mechanical_semi_diameter, s1.clear_semi_diameter) if x is not None]
    if prescription.aperture.kind == "epd":
        radii.append(0.5 * prescription.aperture.value)
    if len(v) == 0:
        return FrontOpening(0.0, max(radii + [1.0]))
    tags = mesh.tags
    hood = [k for k, t in enumerate(mesh.tag_table) if t.kind == "hood"]
    if hood:
        vid = np.unique(mesh.triangles[np.isin(tags, hood)])
        v = v[vid]
    z0 = float(v[:, 2].min())
    extent = float(np.ptp(mesh.vertices, axis=0).max()) or 1.0
    near = v[v[:, 2] <= z0 + 0.01 * extent]
    radii.append(float(np.hypot(near[:, 0], near[:, 1]).max()))
    return FrontOpening(min(z0, 0.0), max(radii))


def object_meshes(spec) -> list[TaggedMesh]:
    """The scene file's extra objects as tagged meshes (kind and role 'object', part = name)."""
    out = []
    for k, o in enumerate(spec.objects):
        if o.type == "disk":
            m = primitives.disk(o.centre_mm, o.radius_mm, tilt_x_deg=o.tilt_deg[0], tilt_y_deg=o.tilt_deg[1],
                                part=o.name, finish=o.finish)
        elif o.type == "rectangle":
            m = primitives.rectangle(o.centre_mm, o.width_mm, o.height_mm, tilt_x_deg=o.tilt_deg[0],
                                     tilt_y_deg=o.tilt_deg[1], part=o.name, finish=o.finish)
        else:
            m = _load_mesh_file(Path(spec.base_dir) / o.path, o, field=f"objects.{k}.path")
        out.append(m)
    return out


def _load_mesh_file(path: Path, o, field: str) -> TaggedMesh:
    if not path.exists():
        raise InputError(f"mesh file '{path}' not found", field=field, valid="an existing .stl/.step file")
    if path.suffix.lower() == ".stl":
        import trimesh  # lazy: trimesh and build123d take seconds to load; only .stl and .step objects need them

        m = trimesh.load(path, force="mesh")
        v, t = np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)
    else:
        from build123d import import_step

        verts, tris = import_step(str(path)).tessellate(0.01, 0.1)
        v = np.array([[p.X, p.Y, p.Z] for p in verts], float)
        t = np.array(tris, np.int64)
    if len(t) == 0:
        raise InputError(f"mesh file '{path}' holds no triangles", field=field, valid="a closed solid")
    rot = primitives.rotation(*o.tilt_deg)
    v = v @ rot.T + np.asarray(o.centre_mm, float)
    return TaggedMesh(v, t, np.zeros(len(t), np.int32), [FaceTag(o.name, "object", "object", o.finish)])


def build_scene(prescription: Prescription, mesh: TaggedMesh, spec, *, bsdf_factory=None) -> Scene:
    """A Scene from the lens, the mount's tagged mesh and a validated SceneSpec.

    bsdf_factory(model, **params) -> BSDF defaults to `lensmount.physics.bsdf.make_bsdf`.
    Raises InputError (with the scene file's line where it has one) for an `[assign]` rule
    that matches no face; `Scene.warnings` lists what is legal but suspicious.
    """
    if bsdf_factory is None:
        bsdf_factory = make_bsdf
    wavelengths = np.asarray(prescription.wavelengths_um, np.float64)
    library = finish_library(spec.finishes)
    treatment = spec.finishes_source  # finishes.toml: where a rule or coating error is
    try:
        check_object_names(spec.objects, mesh.parts)
        mesh = TaggedMesh.concatenate([mesh] + object_meshes(spec))
    except InputError as exc:
        raise located(exc, spec.source_file, spec.source_text) from None
    try:
        check_rules_match(spec.assign, mesh, set(prescription.mirror_surfaces))
    except InputError as exc:
        raise located(exc, *treatment) from None
    # A scene object's own `finish` is as specific as a part rule (an explicit part rule still wins).
    assign = {f"part:{o.name}": o.finish for o in spec.objects} | dict(spec.assign)
    finishes, bsdfs, cache = [], [], {}
    for tag in mesh.tag_table:
        name = finish_of(tag, assign, library)
        finishes.append(name or "")
        if name is None:
            bsdfs.append(None)
            continue
        if name not in cache:
            params = dict(library[name])
            cache[name] = bsdf_factory(params.pop("model"), **params)
        if tag.role == "optical":  # a mirror's coated face: its finish scatters on top of R
            if cache[name].is_delta:
                raise located(InputError(f"surface {tag.surface + 1} is given the finish '{name}', a mirror, although "
                                         "its coating already reflects specularly", field=f"assign.surface:"
                                         f"{tag.surface + 1}", valid="a scatter finish (lambertian, gaussian, abg, "
                                         "harvey, tabulated), or absorber for none; R is the coating's"),
                              *treatment)
            bsdfs.append(MirrorFinish(cache[name]))
            continue
        bsdfs.append(cache[name])

    for key in spec.coatings:
        if key.startswith("surface-") and int(key[8:]) > len(prescription.surfaces):
            raise located(InputError(f"the lens has no surface {key[8:]}", field=f"coatings.{key}",
                                     valid=f"surface-1 to surface-{len(prescription.surfaces)}"), *treatment)
    optical = optical_surfaces(prescription, wavelengths,
                               lambda i, c: spec.coating_of_surface(i, c, prescription.surfaces[i].mirror))
    opening = front_opening(prescription, mesh)
    d = spec.detector
    if d.width_mm is None:
        raise located(InputError("the detector has no size", field="detector.width_mm",
                                 valid="width_mm and height_mm in the scene's [detector], or a scene read "
                                       "with its design folder (the housing's detector size)"),
                      spec.source_file, spec.source_text)
    d = d.fitted(d.width_mm, d.height_mm)
    z_det = float(prescription.image_z if d.z_mm is None else d.z_mm)
    if d.spectral_weight is not None and len(d.spectral_weight) != len(wavelengths):
        raise located(InputError(f"spectral_weight has {len(d.spectral_weight)} values for {len(wavelengths)} "
                                 "wavelengths", field="detector.spectral_weight",
                                 valid=f"{len(wavelengths)} non-negative numbers"), spec.source_file, spec.source_text)
    detector = Detector(d.width_mm, d.height_mm, int(d.pixels[0]), int(d.pixels[1]), z_det, d.spectral_weight,
                        detector_medium_index(prescription, z_det, wavelengths))
    try:
        source = make_source(spec.source, opening, mesh, detector, prescription)
    except InputError as exc:
        raise located(exc, spec.source_file, spec.source_text) from None
    effects = effects_of(spec.effects)
    try:
        check_scatterers(effects, mesh, finishes)
    except InputError as exc:
        raise located(exc, spec.source_file, spec.source_text) from None
    return Scene(mesh=mesh, optical=optical, bsdf_of_tag=bsdfs, source=source, detector=detector,
                 wavelengths_um=wavelengths, effects=effects,
                 entrance_pupil_area_mm2=entrance_pupil_area(prescription),
                 solid_index_of_tag=solid_index_of_tag(prescription, mesh, wavelengths),
                 solid_absorption_of_tag=solid_absorption_of_tag(prescription, mesh, wavelengths),
                 front_opening=opening, finish_of_tag=finishes, description=spec.description,
                 warnings=detector_warnings(mesh, detector) + undecisive_rules(spec.assign, assign, mesh),
                 field_of_view_deg=imaged_field_deg(prescription, detector))


def detector_medium_index(prescription: Prescription, z_det: float, wavelengths_um: np.ndarray) -> tuple[float, ...]:
    """The index (W,) of the image medium when the detector lies in it (behind the face the immersion
    medium begins at, `Prescription.immersion_face`: the specimen plane of an immersion objective), () in air."""
    face = prescription.immersion_face
    if face is None or z_det < prescription.vertex_z[face]:
        return ()
    return tuple(float(n) for n in np.atleast_1d(refractive_index(prescription.image_medium, wavelengths_um)))


def imaged_field_deg(prescription: Prescription, detector: Detector) -> float:
    """The largest off-axis angle the detector images, degrees: the lens's field, or the angle whose
    paraxial image lands at the detector's corner (half diagonal / focal length), the larger;
    180 for a lens without a finite focal length."""
    try:
        efl = abs(float(paraxial(prescription).efl))
    except (ArithmeticError, ValueError):  # InputError included: no paraxial image, nothing to bound
        return 180.0
    if not (math.isfinite(efl) and efl > 0.0):
        return 180.0
    corner = math.degrees(math.atan(0.5 * math.hypot(detector.width, detector.height) / efl))
    return float(max(prescription.max_field_deg, corner))


def entrance_pupil_area(prescription: Prescription) -> float:
    """π (EPD/2)², mm²: what the stray fraction is normalised by. An EPD that cannot be found
    is an error, never 0 (a zero area would read as a stray fraction of 0)."""
    if prescription.aperture.kind == "epd":  # given: no paraxial trace needed (nor a stop)
        epd = float(prescription.aperture.value)
    else:
        epd = float(_pupil(prescription).epd)
    with np.errstate(over="ignore"):
        area = float(np.pi * np.float64(0.5 * epd) ** 2) if math.isfinite(epd) else math.inf
    if not (math.isfinite(area) and epd > 0.0):  # a lens without power gives EPD ~1e299: area overflows
        raise InputError(f"the entrance pupil diameter comes out as {epd:g} mm", field="aperture",
                         valid="a lens whose paraxial entrance pupil diameter is finite and > 0")
    return area


def effects_of(spec) -> Effects:
    """The Scene's Effects from a validated EffectsSpec."""
    selectors = () if isinstance(spec.scatter, bool) else tuple(spec.scatter)
    return Effects(scatter=bool(spec.scatter), ghosts=spec.ghost_order > 0, direct=bool(spec.direct),
                   scatterers=selectors, ghost_order=spec.ghost_order or 2,
                   absorption=bool(spec.absorption))


def check_scatterers(effects: Effects, mesh: TaggedMesh, finishes: list[str]) -> None:
    """InputError for a scatter selector that names no face that can scatter: a misspelt one would
    otherwise turn every face of the run into an absorber without a word."""
    faces = [k for k, t in enumerate(mesh.tag_table) if t.role != "optical" or finishes[k]]
    for sel in effects.scatterers:
        if faces_selected(sel, mesh.tag_table, finishes).any():
            continue
        prefix = sel.partition(":")[0]
        if prefix == "finish":
            names = [finishes[k] for k in faces]
        elif prefix == "surface":
            names = [str(mesh.tag_table[k].surface + 1) for k in faces if mesh.tag_table[k].role == "optical"]
        else:
            names = [str(getattr(mesh.tag_table[k], prefix)) for k in faces]
        present = sorted(set(names))
        guess = did_you_mean(sel.partition(":")[2], present)
        hint = f" (did you mean '{prefix}:{guess}'?)" if guess else ""
        raise InputError(f"scatter selector '{sel}' names no face of the assembly{hint}", field="effects.scatter",
                         valid=f"{prefix}: " + ", ".join(present) + "; or scatter = true for every face")


def _pupil(prescription: Prescription):
    """The paraxial data, or an InputError when the lens has none (no stop, no power)."""
    try:
        return paraxial(prescription)
    except (ArithmeticError, ValueError) as exc:  # InputError included: the lens is what is wrong
        raise InputError(f"the entrance pupil cannot be computed ({exc})", field="aperture",
                         valid="a focal lens with a stop, or an entrance pupil diameter") from None


def check_object_names(objects, parts) -> None:
    """InputError for a scene object named like a mount part or another object: its finish acts
    as a `part:` rule, so it would silently re-finish the mount part of the same name."""
    taken = set(parts)
    for k, o in enumerate(objects):
        if o.name in taken:
            raise InputError(f"the name '{o.name}' is already taken by a part of the assembly or another object",
                             field=f"objects.{k}.name", valid="a name no mount part or other object has; parts: "
                             + ", ".join(sorted(set(parts))))
        taken.add(o.name)


def check_rules_match(assign: dict[str, str], mesh: TaggedMesh, mirrors: set[int] = frozenset()) -> None:
    """InputError for an `[assign]` rule that matches no face: a misspelt selector would
    otherwise leave its faces to the next rule (often an absorber) without a word. `surface:N`
    must name a mirror surface (0-based indices `mirrors`) whose coated face is in the mesh."""
    present = {prefix: sorted({str(getattr(t, prefix)) for t in mesh.tag_table if t.role != "optical"})
               for prefix in ("part", "role", "kind", "finish")}
    present["surface"] = sorted({str(t.surface + 1) for t in mesh.tag_table
                                 if t.role == "optical" and t.surface in mirrors}, key=int)
    for key in assign:
        if key == "*":
            continue
        prefix, _, value = key.partition(":")
        if value in present.get(prefix, ()):
            continue
        guess = did_you_mean(value, present.get(prefix, ()))
        hint = f" (did you mean '{prefix}:{guess}'?)" if guess else ""
        if prefix == "surface":
            raise InputError(f"assignment rule '{key}' names no mirror surface of the assembly (a finish on a "
                             "refracting surface has nothing to scatter with)", field=f"assign.{key}",
                             valid="surface:N for the mirror surfaces " + (", ".join(present["surface"]) or "(none)"))
        raise InputError(f"assignment rule '{key}' matches no face of the assembly{hint}", field=f"assign.{key}",
                         valid="; ".join(f"{p}: {', '.join(v) or '(none)'}" for p, v in present.items()))


def undecisive_rules(rules: dict[str, str], assign: dict[str, str], mesh: TaggedMesh) -> list[str]:
    """A warning for each finishes.toml rule (`rules`) that selects faces but decides none, each of them
    having a more specific assignment in `assign` or in the mount file (a STEP part's face finishes):
    the rule does nothing, which its author should know."""
    decided = {deciding_rule(t, assign) for t in mesh.tag_table}
    out = []
    for key in rules:
        if key in decided or key.startswith("surface:"):
            continue
        prefix, _, value = key.partition(":")
        selected = [t for t in mesh.tag_table if t.role != "optical" and (key == "*" or str(getattr(t, prefix)) == value)]
        why = sorted({f"{t.part} face {t.face} by its {t.assigned} in mount.toml [parts]" if t.assigned
                      else f"{t.part} by '{deciding_rule(t, assign)}'" for t in selected})
        out.append(f"finishes.toml [assign] '{key}' = '{rules[key]}' decides no face: every face it selects has a more "
                   f"specific assignment ({'; '.join(why[:3])}{' …' if len(why) > 3 else ''}); a face's own finish in "
                   "mount.toml is re-mapped only by a 'finish:NAME' rule")
    return out


def detector_warnings(mesh: TaggedMesh, detector: Detector) -> list[str]:
    """A detector whose corners reach into the housing wall: legal (the detector is analytic)
    but suspicious, typically a scene copied from a design with a larger detector."""
    bore = housing_bore_at(mesh, detector.z)
    corner = 0.5 * math.hypot(detector.width, detector.height)
    if bore is None or corner <= bore:
        return []
    return [f"the detector ({detector.width:g} × {detector.height:g} mm, corners at {corner:.2f} mm from the axis) "
            f"is larger than the housing's bore ({bore:.2f} mm radius at the detector plane z = {detector.z:g} mm): "
            "the housing was built for a smaller detector (mount.toml [housing] detector_width_mm, "
            "detector_height_mm), so the detector's outer part lies inside the housing wall"]


def housing_bore_at(mesh: TaggedMesh, z: float) -> float | None:
    """Smallest distance from the axis at which the housing's triangles cross the plane z (mm),
    None without a housing or when the housing does not reach that plane."""
    housing = [k for k, t in enumerate(mesh.tag_table) if t.kind == "housing"]
    if not housing:
        return None
    tri = mesh.vertices[mesh.triangles[np.isin(mesh.tags, housing)]]  # (T, 3, 3)
    radii = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        p, q = tri[:, a], tri[:, b]
        crosses = (p[:, 2] - z) * (q[:, 2] - z) < 0.0
        if crosses.any():
            p, q = p[crosses], q[crosses]
            t = (z - p[:, 2]) / (q[:, 2] - p[:, 2])
            x = p + t[:, None] * (q - p)
            radii.append(np.hypot(x[:, 0], x[:, 1]))
    if not radii:
        return None
    return float(np.concatenate(radii).min())


def solid_index_of_tag(prescription: Prescription, mesh: TaggedMesh, wavelengths_um: np.ndarray) -> np.ndarray:
    """(n_tags, W) index inside the solid each tag bounds: a lens part's glass, 1 elsewhere."""
    return _solid_property(prescription, mesh, wavelengths_um, refractive_index, 1.0)


def solid_absorption_of_tag(prescription: Prescription, mesh: TaggedMesh, wavelengths_um: np.ndarray) -> np.ndarray:
    """(n_tags, W) bulk absorption coefficient (1/mm) inside the solid each tag bounds: a lens
    part's glass (`optics.glass.absorption_coefficient`), 0 elsewhere."""
    return _solid_property(prescription, mesh, wavelengths_um, absorption_coefficient, 0.0)


def _solid_property(prescription, mesh, wavelengths_um, of_material, outside: float) -> np.ndarray:
    """(n_tags, W) of_material(glass, λ) for tags of a lens part, `outside` elsewhere.

    A lens part's glass is the material after its first optical surface (cemented
    elements included: each element's front face is its own)."""
    front: dict[str, int] = {}
    for t in mesh.tag_table:
        if t.kind == "lens" and t.role == "optical" and t.surface >= 0:
            front[t.part] = min(front.get(t.part, t.surface), t.surface)
    out = np.full((len(mesh.tag_table), len(wavelengths_um)), outside)
    for k, t in enumerate(mesh.tag_table):
        if t.part in front:
            out[k] = of_material(prescription.surfaces[front[t.part]].material, wavelengths_um)
    return out


def clear_distance(mesh: TaggedMesh, detector: Detector, opening: FrontOpening) -> float:
    """A distance from the opening's centre beyond which nothing of the assembly lies."""
    pts = [np.array([[0.0, 0.0, detector.z]]), np.array([[0.0, 0.0, opening.z]])]
    if len(mesh.vertices):
        pts.append(mesh.vertices)
    p = np.vstack(pts)
    return float(np.linalg.norm(p - np.array([0.0, 0.0, opening.z]), axis=1).max()
                 + 0.5 * math.hypot(detector.width, detector.height) + 1.0)


def make_source(src: SourceParams, opening: FrontOpening, mesh: TaggedMesh, detector: Detector,
                prescription: Prescription) -> Source:
    """The source of a scene file's [source] table, placed for this assembly: emission discs outside
    it, object planes at the lens's object distance unless the table gives z_mm (physics.sources)."""
    object_z = -float(prescription.object_distance) if prescription.finite_object else None

    def pupil() -> tuple[float, float]:
        par = _pupil(prescription)
        return float(par.entrance_pupil_z), 0.5 * float(par.epd)

    at = Placement(float(opening.z), float(opening.radius), clear_distance(mesh, detector, opening), object_z, pupil,
                   tuple(prescription.wavelength_weights))
    return SOURCES.create(src.type, src, at=at)

__all__ = ["build_scene", "check_rules_match", "check_scatterers", "effects_of", "check_object_names",
           "detector_warnings", "detector_medium_index", "housing_bore_at", "entrance_pupil_area", "imaged_field_deg", "solid_index_of_tag",
           "solid_absorption_of_tag", "optical_surfaces", "front_opening", "object_meshes", "make_source",
           "clear_distance"]
