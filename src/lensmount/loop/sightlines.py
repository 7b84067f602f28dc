"""Lit walls the detector sees: the stray-light engineer's geometric check, no Monte Carlo.

A mount wall matters for stray light when it is both *lit* (the sun, at or beyond the
exclusion angle, reaches it directly: straight in, or refracted through the lens, with no
scatter on the way) and *visible* (the detector sees it: straight, or through the lens).
Both sets come from deterministic ray grids through the real tracer (`trace.tracer.Tracer`):

* visible (`view = "detector"`): backward rays from a grid over the detector's area toward a
  grid over twice the exit pupil (so the walls just outside the beam are looked at); the
  first mechanical face each ray meets is seen. Through the lens the detector sees only what
  lies inside the field's beam (a line of sight passes the stop), so hood walls and vanes,
  which clear the beam, are never seen this way;
* visible (`view = "aperture"`): what the entrance aperture sees, the classic baffle
  criterion: rays from a grid over the first surface's clear aperture into the whole
  half space in front of it. A lit wall seen from there sends light onto the first lens,
  whose scatter (and the mount behind it) can bring it to the detector: the walls the
  line-of-sight vane construction hides;
* lit: forward rays on a square grid covering the front opening, from the sun at the
  exclusion angle and at a ladder of larger angles up to 89°; the first mechanical face
  each ray meets is lit. For a lens whose object is at a finite distance the light comes from
  its object plane instead: from the point seen at each of those angles from the entrance pupil
  (`optics.paraxial.object_height_at`, as the file's fields are) toward the same grid.

The mount is a solid of revolution, so the sun's azimuth only rotates the lit pattern; the
sets are compared in the (r, z) half plane, per face, in cells of CELL_MM: a cell hit by a
lit ray and by a visible ray is a lit wall the detector sees. Its area is that of the band
the cell sweeps about the axis (2π r·CELL_MM): a measure, not a CAD area.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lensmount.design.scene import scene_from_dict
from lensmount.mesh import TaggedMesh
from lensmount.optics.apertures import with_clear_semi_diameters
from lensmount.optics.paraxial import object_height_at, paraxial
from lensmount.optics.prescription import Prescription
from lensmount.optics.profiles import Profile
from lensmount.physics.rays import RayBatch
from lensmount.physics.sources import orthonormal_basis, source_direction
from lensmount.run.results import save_figure
from lensmount.trace.tracer import FACE, Tracer

CELL_MM = 0.2
DETECTOR_GRID = (15, 11)
PUPIL_RINGS, PUPIL_SPOKES = 8, 36
PUPIL_SCALE = 2.0
SUN_GRID = 120  # per side of the square over the front opening
SUN_STEPS_DEG = (0.0, 0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 8.0, 12.0, 20.0, 30.0, 45.0, 60.0)
# steep suns the ladder above the exclusion angle stops short of: only they reach a hood's
# bore right behind the mouth vane
STEEP_SUN_DEG = (70.0, 80.0, 89.0)
SUN_AZIMUTHS_DEG = (0.0, 45.0)  # two, so a facet pattern cannot hide a lit band
APERTURE_RINGS, APERTURE_SPOKES = 8, 24
LOOK_POLAR, LOOK_AZIMUTHS = 45, 48  # directions over the half space in front of the aperture
VIEWS = ("detector", "aperture")


def file_stem(view: str) -> str:
    """The check's file names per view (check.png/json from the detector, check-aperture.* from the
    entrance aperture), so one view's run never overwrites the other's."""
    return "check" if view == "detector" else f"check-{view}"


@dataclass
class LitWall:
    part: str
    kind: str
    role: str
    face: int
    area_mm2: float
    z_range: tuple[float, float]
    r_range: tuple[float, float]
    smallest_angle_deg: float  # the smallest sun angle that lights the seen cells
    label: str = ""  # the face's name in a user's STEP file


@dataclass
class SightlineReport:
    exclusion_deg: float
    view: str
    walls: list[LitWall]
    visible_points: np.ndarray  # (n, 2) (r, z) of backward hits on mechanical faces
    lit_points: np.ndarray      # (m, 2) (r, z) of forward hits
    both_points: np.ndarray     # (k, 2) cell centres both lit and seen
    rays: dict = field(default_factory=dict)
    edges: list[LitWall] = field(default_factory=list)  # lit vane edges seen from the aperture (not failures)
    lit_by: str = "the sun"  # or "the object plane": a finite object's own plane lights the mount

    @property
    def passed(self) -> bool:
        return not self.walls


def _scene(prescription: Prescription, mesh: TaggedMesh, width: float, height: float, exclusion_deg: float):
    # lazy: keeps lensmount --help from loading scene.build and the BSDF models
    from lensmount.scene.build import build_scene

    spec = scene_from_dict({"source": {"type": "collimated", "off_axis_deg": exclusion_deg},
                            "detector": {"width_mm": width, "height_mm": height, "pixels": [1, 1]},
                            "effects": {"scatter": True, "ghosts": False, "direct": False}})
    return build_scene(prescription, mesh, spec)


def _first_faces(tracer, origins, directions):
    """(tags, points) of the rays whose first event is a mechanical face."""
    ev = tracer.next_event(RayBatch.make(origins, directions))
    hit = ev.kind == FACE
    return ev.tag[hit], ev.position[hit]


def _cells(tags, points):
    r = np.hypot(points[:, 0], points[:, 1])
    return np.column_stack([tags, np.floor(r / CELL_MM), np.floor(points[:, 2] / CELL_MM)]).astype(np.int64)


def _aperture_rays(prescription: Prescription):
    """(origins, directions): a grid over surface 1's clear aperture, just in front of it, looking
    into object space: every direction on the air side of the surface's tangent plane there (a
    chord across a convex front surface would look through the glass, not into the hood)."""
    s = prescription.surfaces[0]
    prof = Profile.of(s)
    rho = np.sqrt((np.arange(APERTURE_RINGS) + 0.5) / APERTURE_RINGS) * float(s.clear_semi_diameter)
    phi = np.arange(APERTURE_SPOKES) * 2 * np.pi / APERTURE_SPOKES
    rr, pp = (g.ravel() for g in np.meshgrid(rho, phi))
    local = np.column_stack([rr * np.cos(pp), rr * np.sin(pp), prof.sag(rr * rr)])
    theta = np.radians(np.linspace(0.0, 89.5, LOOK_POLAR))
    psi = np.arange(LOOK_AZIMUTHS) * 2 * np.pi / LOOK_AZIMUTHS
    tt, qq = (g.ravel() for g in np.meshgrid(theta, psi))
    looks = np.column_stack([np.sin(tt) * np.cos(qq), np.sin(tt) * np.sin(qq), -np.cos(tt)])
    o = np.repeat(local + [0.0, 0.0, prescription.vertex_z[0] - 1e-4], len(looks), axis=0)
    d = np.tile(looks, (len(local), 1))
    air_side = (d * np.repeat(prof.normal(local), len(looks), axis=0)).sum(axis=1) < -1e-9  # normal points +z
    return o[air_side], d[air_side]


def lit_walls_seen(prescription: Prescription, mesh: TaggedMesh, detector_mm: tuple[float, float],
                   exclusion_deg: float, view: str = "detector") -> SightlineReport:
    """Every mount face both lit by the sun (a finite object: its object plane) at >= exclusion_deg and seen from `view`: the
    detector (through the lens) or the entrance aperture (VIEWS; module docstring). Seen from
    the aperture, lit vane edges are unavoidable (every edge is both): they are listed in
    `report.edges`, not as failures."""
    if view not in VIEWS:
        raise ValueError(f"view {view!r} is not one of {VIEWS}")
    p = prescription
    if p.surfaces[0].clear_semi_diameter is None:
        p = with_clear_semi_diameters(p)
    w, h = detector_mm
    scene = _scene(p, mesh, w, h, exclusion_deg)
    tracer = Tracer(scene)
    o, d = _aperture_rays(p) if view == "aperture" else _detector_rays(scene, paraxial(p), w, h)
    v_tags, v_pts = _first_faces(tracer, o, d)
    report = _compare(p, mesh, tracer, scene, exclusion_deg, view, v_tags, v_pts, len(o))
    if view == "aperture":
        report.edges = [wl for wl in report.walls if wl.role == "vane-edge"]
        report.walls = [wl for wl in report.walls if wl.role != "vane-edge"]
    return report


def _detector_rays(scene, par, w: float, h: float):
    """(origins, directions): a grid over the detector toward a grid over twice the exit pupil."""
    nx, ny = DETECTOR_GRID
    gx, gy = np.meshgrid(np.linspace(-0.5 * w, 0.5 * w, nx), np.linspace(-0.5 * h, 0.5 * h, ny))
    z_det = scene.detector.z
    det = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, z_det - 1e-6)])
    rho = np.sqrt((np.arange(PUPIL_RINGS) + 0.5) / PUPIL_RINGS) * 0.5 * PUPIL_SCALE * par.exit_pupil_diameter
    phi = np.arange(PUPIL_SPOKES) * 2 * np.pi / PUPIL_SPOKES
    rr, pp = np.meshgrid(rho, phi)
    pupil = np.column_stack([(rr * np.cos(pp)).ravel(), (rr * np.sin(pp)).ravel(),
                             np.full(rr.size, par.exit_pupil_z)])
    o = np.repeat(det, len(pupil), axis=0)
    d = np.tile(pupil, (len(det), 1)) - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, d


def _lit_rays(p: Prescription, opening, reach: float, th: float, az: float, su, sv):
    """(origins, directions) of the light at angle th (deg), azimuth az (deg) over the front opening's
    grid (su, sv in the unit disc): parallel from the sun, or from the point of a finite object's plane."""
    radius = opening.radius * 1.02 + 1e-3
    if p.finite_object:   # the point toward azimuth az, as a scene's point source sits
        h, a = object_height_at(p, th), math.radians(az)
        point = np.array([h * math.cos(a), h * math.sin(a), -p.object_distance])
        d = np.column_stack([radius * su, radius * sv, np.full(len(su), opening.z)]) - point
        return np.tile(point, (len(su), 1)), d / np.linalg.norm(d, axis=1, keepdims=True)
    ds = source_direction(th, az)
    e1, e2 = orthonormal_basis(ds)
    # a disc normal to the light, set back beyond the assembly, covering the front opening
    centre = np.array([0.0, 0.0, opening.z]) - reach * ds
    return centre + radius * (su[:, None] * e1 + sv[:, None] * e2), np.tile(ds, (len(su), 1))


def _compare(p, mesh, tracer, scene, exclusion_deg, view, v_tags, v_pts, n_seen_rays) -> SightlineReport:
    """Trace the light at and beyond the exclusion angle; the faces both lit and seen, per (r, z) cell."""
    # ---- lit: the sun (or the object plane) at and beyond the exclusion angle ----------
    opening = scene.front_opening
    reach = float(np.linalg.norm(mesh.vertices - [0.0, 0.0, opening.z], axis=1).max()) + 1.0
    u = (np.arange(SUN_GRID) + 0.5) / SUN_GRID * 2 - 1
    su, sv = np.meshgrid(u, u)
    inside = su ** 2 + sv ** 2 <= 1.0
    l_tags, l_pts, l_angle = [], [], []
    angles = sorted({a for a in (exclusion_deg + s for s in SUN_STEPS_DEG) if a < 89.5}
                    | {a for a in STEEP_SUN_DEG if a > exclusion_deg})
    for th in angles:
        for az in SUN_AZIMUTHS_DEG:
            starts, dirs = _lit_rays(p, opening, reach, th, az, su[inside], sv[inside])
            t, q = _first_faces(tracer, starts, dirs)
            l_tags.append(t)
            l_pts.append(q)
            l_angle.append(np.full(len(t), th))
    l_tags, l_pts, l_angle = np.concatenate(l_tags), np.concatenate(l_pts), np.concatenate(l_angle)
    # ---- compare in the (r, z) half plane, per face ------------------------------------
    vc, lc = _cells(v_tags, v_pts), _cells(l_tags, l_pts)
    seen = {tuple(c) for c in vc}
    both = {}
    for c, a in zip(map(tuple, lc), l_angle):
        if c in seen:
            both[c] = min(both.get(c, np.inf), float(a))
    walls = []
    by_face: dict[int, list] = {}
    for (tag, ir, iz), a in both.items():
        by_face.setdefault(tag, []).append((ir, iz, a))
    for tag, cells in sorted(by_face.items()):
        t = mesh.tag_table[tag]
        arr = np.array(cells, dtype=np.float64)
        r = (arr[:, 0] + 0.5) * CELL_MM
        z = (arr[:, 1] + 0.5) * CELL_MM
        walls.append(LitWall(t.part, t.kind, t.role, int(t.face), float((2 * math.pi * r * CELL_MM).sum()),
                             (float(z.min() - 0.5 * CELL_MM), float(z.max() + 0.5 * CELL_MM)),
                             (float(r.min() - 0.5 * CELL_MM), float(r.max() + 0.5 * CELL_MM)),
                             float(arr[:, 2].min()), t.label))
    walls.sort(key=lambda wl: -wl.area_mm2)
    both_pts = np.array([((ir + 0.5) * CELL_MM, (iz + 0.5) * CELL_MM) for (_, ir, iz) in both]).reshape(-1, 2)
    return SightlineReport(exclusion_deg, view, walls, np.column_stack([np.hypot(v_pts[:, 0], v_pts[:, 1]), v_pts[:, 2]]),
                           np.column_stack([np.hypot(l_pts[:, 0], l_pts[:, 1]), l_pts[:, 2]]), both_pts,
                           {"backward": int(n_seen_rays), "forward": int(len(angles) * len(SUN_AZIMUTHS_DEG) * inside.sum())},
                           lit_by="the object plane" if p.finite_object else "the sun")


def plot_report(report: SightlineReport, mesh: TaggedMesh, path) -> None:
    """check.png (`file_stem`): the mount's (r, z) section, seen points, lit points and the lit walls seen."""
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(11, 4.5), dpi=110)
    v = mesh.vertices
    ax.plot(v[:, 2], np.hypot(v[:, 0], v[:, 1]), ",", color="0.75")
    if len(report.visible_points):
        ax.plot(report.visible_points[:, 1], report.visible_points[:, 0], ".", ms=1, color="tab:blue",
                label=f"seen from the {'entrance aperture' if report.view == 'aperture' else 'detector'}")
    if len(report.lit_points):
        ax.plot(report.lit_points[:, 1], report.lit_points[:, 0], ".", ms=1, color="tab:orange", alpha=0.4,
                label=f"lit by {report.lit_by} at ≥ {report.exclusion_deg:g}°")
    if len(report.both_points):
        ax.plot(report.both_points[:, 1], report.both_points[:, 0], "s", ms=4, color="red",
                label="lit and seen")
    ax.set_xlabel("z (mm)")
    ax.set_ylabel("r (mm)")
    verdict = "PASS: no lit wall is seen" if report.passed else \
        f"FAIL: {len(report.walls)} lit face(s) seen, first {report.walls[0].part} face {report.walls[0].face}"
    ax.set_title(f"lensmount check — {report.lit_by} at ≥ {report.exclusion_deg:g}° — {verdict}")
    ax.legend(loc="upper right", markerscale=3, fontsize=8)
    fig.tight_layout()
    save_figure(fig, path)


__all__ = ["lit_walls_seen", "plot_report", "SightlineReport", "LitWall", "VIEWS", "file_stem"]
