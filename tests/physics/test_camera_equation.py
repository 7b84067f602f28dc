"""The camera equation through the real tracer: a Lambertian plate imaged by a singlet.

A plate of reflectance ρ under irradiance E (the sun at θ_i to its normal, E = E_sun cos θ_i)
has radiance L = ρ E / π. Radiance is conserved through lossless optics (perfect AR, T = 1, the
glass's bulk absorption off: `Effects.absorption = False`),
so the on-axis image irradiance is L times the projected solid angle of the exit pupil:

    E_img = π L sin²θ' = ρ E T / (4 N_w²),   N_w = 1 / (2 sin θ')

with sin θ' from the exit pupil's paraxial size and position (lensmount.optics.paraxial,
the optics engineer's code, not the integrator's). A missing cos θ, π, 1/S or A_D in the
bidirectional estimator shows up here as a factor.
"""

import math

import numpy as np
import pytest

from lensmount.mesh import TaggedMesh
from lensmount.integrators.bidirectional import bidirectional_pass
from lensmount.optics.paraxial import paraxial
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene import primitives
from lensmount.scene.build import optical_surfaces, solid_absorption_of_tag, solid_index_of_tag
from lensmount.scene.scene import Effects, Scene
from lensmount.physics.bsdf import make_bsdf
from lensmount.physics.detector import Detector
from lensmount.physics.interfaces import parse_coating
from lensmount.physics.sources import EmissionDisc, SunSource, source_direction
from lensmount.trace.tracer import Tracer

RHO = 0.5
SUN_DEG = 120.0  # the sun behind the camera, 60° from the plate's normal: E = E_sun · cos 60°
D = 2000.0       # plate distance in front of surface 1, mm
H = 6.25         # stop (surface 1) semi-diameter: f/8 at f = 100 mm


def camera_scene():
    lens = Prescription((Surface(51.68, 4.0, "N-BK7", is_stop=True, clear_semi_diameter=H,
                                 mechanical_semi_diameter=H + 0.05),
                         Surface(math.inf, 100.0, "AIR", clear_semi_diameter=H, mechanical_semi_diameter=H + 0.05)),
                        Aperture("epd", 2 * H), (0.5875618,), (1.0,), 0, (0.0,), "singlet")
    par = paraxial(lens)
    # Detector at the paraxial image of the plate: object at −D through the system matrix.
    z_img = _image_z(par.efl, lens, D)
    wl = np.array([0.5875618])
    mesh = TaggedMesh.concatenate([
        primitives.lens_elements(lens, [H + 0.05, H + 0.05], rings=24, segments=128),
        primitives.tube(-1.0, z_img + 1.0, H, H + 3.0, part="barrel", finish="absorber"),
        primitives.disk((0.0, 0.0, -D), 30.0, part="plate", segments=128),
    ])
    bsdfs = [None if t.role == "optical" else (make_bsdf("lambertian", reflectance=RHO) if t.part == "plate"
                                              else make_bsdf("absorber")) for t in mesh.tag_table]
    d = source_direction(SUN_DEG, 90.0)
    disc = EmissionDisc(tuple(float(x) for x in np.array([0, 0, -D]) - 3000.0 * d), 34.0)
    scene = Scene(mesh=mesh, optical=optical_surfaces(lens, wl, lambda i, c: parse_coating("perfect-ar")),
                  bsdf_of_tag=bsdfs, source=SunSource(SUN_DEG, 90.0, disc), detector=Detector(0.4, 0.4, 2, 2, z_img),
                  wavelengths_um=wl, effects=Effects(True, False, False, absorption=False),
                  entrance_pupil_area_mm2=math.pi * H * H, solid_index_of_tag=solid_index_of_tag(lens, mesh, wl),
                  solid_absorption_of_tag=solid_absorption_of_tag(lens, mesh, wl))
    return scene, lens, par, z_img


def _image_z(efl, lens, dist):
    """Paraxial image of an axial point at z = −dist (2×2 y–nu matrices, independent of the code under test)."""
    from lensmount.optics.glass import refractive_index

    y, nu, n = 1.0, 1.0 / dist, 1.0  # ray from the object point through height 1 at surface 1
    z = 0.0
    for i, s in enumerate(lens.surfaces):
        n2 = float(np.atleast_1d(refractive_index(s.material, 0.5875618))[0])
        nu = nu - y * (n2 - n) * s.curvature
        n = n2
        if i < len(lens.surfaces) - 1:
            y = y + s.thickness * nu / n
            z += s.thickness
    return z + y / (-nu / n)


def test_camera_equation_on_axis():
    scene, lens, par, z_img = camera_scene()
    tracer = Tracer(scene)
    est = [bidirectional_pass(scene, tracer, 300_000, 21, i, 1.0, samples_per_pixel=5000) for i in range(4)]
    vals = np.array([e.image.mean() for e in est])
    mean, se = vals.mean(), vals.std(ddof=1) / 2
    # Exit pupil seen from the image point: sin²θ' = h² / (h² + Δz²).
    h = 0.5 * par.exit_pupil_diameter
    dz = z_img - par.exit_pupil_z
    sin2 = h * h / (h * h + dz * dz)
    n_w = 1.0 / (2.0 * math.sqrt(sin2))
    expected = RHO * math.cos(math.radians(180.0 - SUN_DEG)) / (4.0 * n_w**2)
    # Paraxial working f-number for a finite conjugate, (1 + |m|) N: the same within 1 %.
    m = (z_img - lens.vertex_z[-1]) / D
    assert n_w == pytest.approx(par.f_number * (1 + abs(m)), rel=0.02)
    assert np.all(np.isfinite(vals))
    assert abs(mean - expected) < 3 * se + 0.02 * expected, (mean, se, expected)
