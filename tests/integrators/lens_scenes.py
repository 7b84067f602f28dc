"""Lens scenes for the integrator tests, built without the CAD layer (numpy primitives).

- `double_gauss_case(case, ...)`: the reference double Gauss (public reference data in
  /work/shared/reference/double-gauss-360.md) in an absorbing barrel with a diaphragm whose
  faces carry separate tags — front, back, the 50 µm inner edge (role `diaphragm-edge`) — as
  the CAD tessellation does, and the paper's three finishes.
- The scene is assembled with the scene engineer's `Scene` dataclass and `optical_surfaces`.
"""

from __future__ import annotations

import math

import numpy as np

from lensmount.mesh import FaceTag, TaggedMesh
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene import primitives
from lensmount.scene.build import (detector_medium_index, imaged_field_deg, optical_surfaces, solid_absorption_of_tag,
                                   solid_index_of_tag)
from lensmount.scene.scene import Effects, Scene
from lensmount.physics.bsdf import make_bsdf
from lensmount.physics.detector import Detector
from lensmount.physics.interfaces import parse_coating
from lensmount.physics.sources import EmissionDisc, SunSource, source_direction

ROWS = [  # radius, thickness, material, stop
    (202.328568, 31.5, "SCHOTT:N-SSK2", False), (548.22888, 1.8, "AIR", False),
    (135.657432, 45.0, "SCHOTT:N-SK2", False), (math.inf, 13.68, "SCHOTT:F5", False),
    (87.23268, 58.930002, "AIR", False), (math.inf, 49.4926452, "AIR", True),
    (-102.158316, 13.68, "SCHOTT:F5", False), (math.inf, 39.6, "SCHOTT:N-SK16", False),
    (-136.531656, 1.8, "AIR", False), (638.682336, 25.2, "SCHOTT:N-SK16", False),
    (-285.881148, 221.3551296, "AIR", False),
]
SD = [46.0, 44.0, 40.0, 38.0, 34.0, 25.715, 33.0, 38.0, 40.0, 43.0, 43.0]  # stop: EPD-matched (f/7)


def double_gauss() -> Prescription:
    surfaces = [Surface(radius=r, thickness=t, material=m, is_stop=s, clear_semi_diameter=sd,
                        mechanical_semi_diameter=sd + 1.0) for (r, t, m, s), sd in zip(ROWS, SD)]
    return Prescription(tuple(surfaces), Aperture("fno", 7.0), (0.5875618,), (1.0,), 0, (0.0, 3.5, 5.0),
                        "double-gauss-360")


def annulus(z, r_in, r_out, *, facing, tag, segments=256):
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    v = np.vstack([np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(segments, z)]) for r in (r_in, r_out)])
    i = np.arange(segments)
    j = (i + 1) % segments
    t = np.vstack([np.column_stack([i, segments + i, segments + j]), np.column_stack([i, segments + j, j])])
    if facing < 0:
        t = t[:, ::-1]
    return TaggedMesh(v, t, np.zeros(len(t), np.int32), [tag])


def cylinder(z0, z1, r, *, tag, inward, segments=256):
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    v = np.vstack([np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(segments, z)]) for z in (z0, z1)])
    i = np.arange(segments)
    j = (i + 1) % segments
    t = np.vstack([np.column_stack([i, j, segments + j]), np.column_stack([i, segments + j, segments + i])])
    if inward:
        t = t[:, ::-1]
    return TaggedMesh(v, t, np.zeros(len(t), np.int32), [tag])


def diaphragm(z, r_in, r_out, width=0.05, segments=512):
    """A plate of thickness `width` with a cylindrical inner edge: four faces, four tags."""
    f = lambda role, k: FaceTag("diaphragm", "diaphragm", role, "x", face=k)  # noqa: E731
    return TaggedMesh.concatenate([
        annulus(z - width / 2, r_in, r_out, facing=-1, tag=f("mount", 0), segments=segments),
        annulus(z + width / 2, r_in, r_out, facing=+1, tag=f("mount", 1), segments=segments),
        cylinder(z - width / 2, z + width / 2, r_in, tag=f("diaphragm-edge", 2), inward=True, segments=segments),
        cylinder(z - width / 2, z + width / 2, r_out, tag=f("mount", 3), inward=False, segments=segments),
    ])


def barrel(z0, z1, r_in, r_out, *, part="barrel", segments=256):
    """A closed tube with one tag per CAD face (inner wall, outer wall, two ends), as the CAD layer tags."""
    f = lambda k: FaceTag(part, "barrel", "mount", "x", face=k)  # noqa: E731
    return TaggedMesh.concatenate([
        cylinder(z0, z1, r_in, tag=f(0), inward=True, segments=segments),
        cylinder(z0, z1, r_out, tag=f(1), inward=False, segments=segments),
        annulus(z0, r_in, r_out, facing=-1, tag=f(2), segments=segments),
        annulus(z1, r_in, r_out, facing=+1, tag=f(3), segments=segments),
    ])


def double_gauss_case(case: int = 1, *, off_axis_deg=7.0, pixels=(60, 60), edge_width=0.05, gauss_deg=5.0,
                      reflectance=None, ghosts=False):
    """The paper's case 1 (Lambertian 10 % diaphragm edge), 2 (mount Lambertian 5 %) or 3 (Gaussian 5°)."""
    lens = double_gauss()
    zs = lens.vertex_z
    stop = lens.stop_index
    sds = [s.mechanical_semi_diameter for s in lens.surfaces]
    z_img = lens.image_z
    r_barrel = max(sds) + 0.5
    mesh = TaggedMesh.concatenate([
        primitives.lens_elements(lens, sds, rings=24, segments=128, finish="x"),
        barrel(-20.0, z_img - 5.0, r_barrel, r_barrel + 5.0),
        diaphragm(zs[stop], SD[stop], r_barrel, edge_width),
    ])
    wl = np.array([0.5875618])
    rho_edge = 0.10 if reflectance is None else reflectance
    rho_mount = 0.05 if reflectance is None else reflectance
    bsdfs = []
    for t in mesh.tag_table:
        if t.role == "optical":
            bsdfs.append(None)
        elif case == 1:
            bsdfs.append(make_bsdf("lambertian", reflectance=rho_edge) if t.role == "diaphragm-edge"
                         else make_bsdf("absorber"))
        elif t.role == "diaphragm-edge":
            bsdfs.append(make_bsdf("absorber"))
        elif case == 2:
            bsdfs.append(make_bsdf("lambertian", reflectance=rho_mount))
        else:
            bsdfs.append(make_bsdf("gaussian", reflectance=rho_mount, half_width_deg=gauss_deg))
    d = source_direction(off_axis_deg, 90.0)
    disc = EmissionDisc(tuple(float(x) for x in np.array([0.0, 0.0, -20.0]) - 1500.0 * d),
                        r_barrel + 6.0 + 1500.0 * math.tan(math.radians(0.27)))
    side = 2 * 360.0 * math.tan(math.radians(5.0)) / math.sqrt(2)
    coating = parse_coating("perfect-ar")
    return Scene(mesh=mesh, optical=optical_surfaces(lens, wl, lambda i, c: coating), bsdf_of_tag=bsdfs,
                 source=SunSource(off_axis_deg, 90.0, disc), detector=Detector(side, side, *pixels, z_img),
                 wavelengths_um=wl, effects=Effects(True, ghosts, False),
                 entrance_pupil_area_mm2=math.pi * 25.715**2, solid_index_of_tag=solid_index_of_tag(lens, mesh, wl),
                 solid_absorption_of_tag=solid_absorption_of_tag(lens, mesh, wl))


def singlet_barrel(bsdf, *, off_axis_deg=8.0, pixels=(16, 16), detector_mm=20.0, ghosts=False, direct=False,
                   coating="perfect-ar", absorption=True):
    """A 100 mm f/4 singlet in a barrel whose inside scatters with `bsdf`: forward converges fast here."""
    h = 12.5
    lens = Prescription((Surface(51.68, 6.0, "N-BK7", is_stop=True, clear_semi_diameter=h, mechanical_semi_diameter=h),
                         Surface(math.inf, 96.0, "AIR", clear_semi_diameter=h, mechanical_semi_diameter=h)),
                        Aperture("epd", 2 * h), (0.5875618,), (1.0,), 0, (0.0,), "singlet")
    z_img = lens.image_z
    mesh = TaggedMesh.concatenate([
        primitives.lens_elements(lens, [h, h], rings=24, segments=128, finish="x"),
        barrel(-30.0, z_img + 2.0, h, h + 3.0, segments=128),
    ])
    wl = np.array([0.5875618])
    bsdfs = [None if t.role == "optical" else (bsdf if t.part == "barrel" else make_bsdf("absorber"))
             for t in mesh.tag_table]
    d = source_direction(off_axis_deg, 90.0)
    disc = EmissionDisc(tuple(float(x) for x in np.array([0.0, 0.0, -30.0]) - 500.0 * d), h + 4.0 + 500 * 0.005)
    coating = parse_coating(coating)
    return Scene(mesh=mesh, optical=optical_surfaces(lens, wl, lambda i, c: coating), bsdf_of_tag=bsdfs,
                 source=SunSource(off_axis_deg, 90.0, disc),
                 detector=Detector(detector_mm, detector_mm, *pixels, z_img), wavelengths_um=wl,
                 effects=Effects(True, ghosts, direct, absorption=absorption), entrance_pupil_area_mm2=math.pi * h * h,
                 solid_index_of_tag=solid_index_of_tag(lens, mesh, wl),
                 solid_absorption_of_tag=solid_absorption_of_tag(lens, mesh, wl),
                 field_of_view_deg=imaged_field_deg(lens, Detector(detector_mm, detector_mm, 1, 1, z_img)))


def glass_rim(off_axis_deg=20.0, *, material="N-BK7", barrel_gap=0.2, pixels=(16, 16), detector_mm=80.0):
    """f/4 singlet whose ground rim scatters (Lambertian 0.5) inside a black barrel: much of the
    rim's light is scattered from INSIDE the glass (the n² case of the review)."""
    h = 12.5
    lens = Prescription((Surface(51.68, 6.0, material, is_stop=True, clear_semi_diameter=h, mechanical_semi_diameter=h),
                         Surface(math.inf, 96.0, "AIR", clear_semi_diameter=h, mechanical_semi_diameter=h)),
                        Aperture("epd", 2 * h), (0.5875618,), (1.0,), 0, (0.0,), "singlet")
    z_img = lens.image_z
    mesh = TaggedMesh.concatenate([
        primitives.lens_elements(lens, [h, h], rings=24, segments=128, finish="x"),
        barrel(-30.0, z_img + 2.0, h + barrel_gap, h + barrel_gap + 3.0, segments=128),
    ])
    wl = np.array(lens.wavelengths_um)
    rim, black = make_bsdf("lambertian", reflectance=0.5), make_bsdf("absorber")
    bsdfs = [None if t.role == "optical" else (rim if t.role == "lens-edge" else black) for t in mesh.tag_table]
    d = source_direction(off_axis_deg, 90.0)
    disc = EmissionDisc(tuple(float(x) for x in np.array([0.0, 0.0, -30.0]) - 500.0 * d),
                        h + barrel_gap + 4.0 + 500 * 0.005)
    coating = parse_coating("perfect-ar")
    return Scene(mesh=mesh, optical=optical_surfaces(lens, wl, lambda i, c: coating), bsdf_of_tag=bsdfs,
                 source=SunSource(off_axis_deg, 90.0, disc), detector=Detector(detector_mm, detector_mm, *pixels, z_img),
                 wavelengths_um=wl, effects=Effects(True, False, False), entrance_pupil_area_mm2=math.pi * h * h,
                 solid_index_of_tag=solid_index_of_tag(lens, mesh, wl),
                 solid_absorption_of_tag=solid_absorption_of_tag(lens, mesh, wl))


def immersed_singlet(bsdf, *, medium="1.333/0", off_axis_deg=20.0, pixels=(16, 16), detector_mm=40.0):
    """`singlet_barrel`'s f/4 singlet with its plane back face in contact with `medium`, which fills the
    96 mm to the detector (an immersion image): only the barrel in front of the lens scatters, so every
    detector photon has crossed the lens into the medium (the barrel beside the medium absorbs)."""
    h = 12.5
    lens = Prescription((Surface(51.68, 6.0, "N-BK7", is_stop=True, clear_semi_diameter=h, mechanical_semi_diameter=h),
                         Surface(math.inf, 96.0, medium, clear_semi_diameter=h, mechanical_semi_diameter=h)),
                        Aperture("epd", 2 * h), (0.5875618,), (1.0,), 0, (0.0,), "immersed singlet")
    z_img = lens.image_z
    mesh = TaggedMesh.concatenate([
        primitives.lens_elements(lens, [h, h], rings=24, segments=128, finish="x"),
        barrel(-30.0, 0.0, h, h + 3.0, segments=128),
        barrel(0.0, z_img + 2.0, h, h + 3.0, part="rear-barrel", segments=128),
    ])
    wl = np.array([0.5875618])
    bsdfs = [None if t.role == "optical" else (bsdf if t.part == "barrel" else make_bsdf("absorber"))
             for t in mesh.tag_table]
    d = source_direction(off_axis_deg, 90.0)
    disc = EmissionDisc(tuple(float(x) for x in np.array([0.0, 0.0, -30.0]) - 500.0 * d), h + 4.0 + 500 * 0.005)
    detector = Detector(detector_mm, detector_mm, *pixels, z_img, medium_index=detector_medium_index(lens, z_img, wl))
    return Scene(mesh=mesh, optical=optical_surfaces(lens, wl, lambda i, c: parse_coating("perfect-ar")),
                 bsdf_of_tag=bsdfs, source=SunSource(off_axis_deg, 90.0, disc), detector=detector,
                 wavelengths_um=wl, effects=Effects(True, False, False), entrance_pupil_area_mm2=math.pi * h * h,
                 solid_index_of_tag=solid_index_of_tag(lens, mesh, wl),
                 solid_absorption_of_tag=solid_absorption_of_tag(lens, mesh, wl),
                 field_of_view_deg=imaged_field_deg(lens, detector))


def bare_edge(off_axis_deg=7.0, *, r=5.0, width=0.2, pixels=(4, 4)):
    """A diaphragm alone (hole radius r, plate `width` thick) under the sun, its cylindrical inner edge the
    only face that scatters (Lambertian 10 %), in a black barrel; no lens, so the edge's entrance pupil is
    its own rim. Sunlight of unit irradiance along d (θ off axis) falls on the lit half of the edge with
    flux 2 r · width · sin θ (its projection along d: no other face shades it for width · tan θ ≪ r)."""
    mesh = TaggedMesh.concatenate([diaphragm(0.0, r, r + 4.0, width, segments=256),
                                   barrel(-10.0, 32.0, r + 4.0, r + 6.0, segments=64)])
    bsdfs = [make_bsdf("lambertian", reflectance=0.1) if t.role == "diaphragm-edge" else make_bsdf("absorber")
             for t in mesh.tag_table]
    d = source_direction(off_axis_deg, 90.0)
    disc = EmissionDisc(tuple(float(x) for x in np.array([0.0, 0.0, -10.0]) - 100.0 * d), r + 7.0)
    n = len(mesh.tag_table)
    return Scene(mesh=mesh, optical=[], bsdf_of_tag=bsdfs, source=SunSource(off_axis_deg, 90.0, disc),
                 detector=Detector(6.0, 6.0, *pixels, 30.0), wavelengths_um=np.array([0.5875618]),
                 effects=Effects(True, False, False), entrance_pupil_area_mm2=math.pi * r * r,
                 solid_index_of_tag=np.ones((n, 1)), solid_absorption_of_tag=np.zeros((n, 1)))
