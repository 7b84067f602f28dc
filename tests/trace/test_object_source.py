"""Finite conjugates: a point or disc source on the object plane of a singlet, through the real tracer.

The lens is a plano-convex N-BK7 singlet (R = 51.68 mm, t = 4 mm, curved side to the object) stopped
at its front face. Everything expected is worked out here by hand: the thin-lens conjugate equation
measured from the principal planes of a plano-convex lens (H on the curved vertex, H' at t − t/n),
and the normalisation (ObjectSource: what enters the entrance pupil is the flux A_EP).
"""

import math

import numpy as np
import pytest

from tests.trace.geometry import make_scene
from lensmount.mesh import TaggedMesh
from lensmount.errors import InputError
from lensmount.optics.glass import refractive_index
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene import primitives
from lensmount.physics.sampler import stream
from lensmount.trace.tracer import DETECTOR, Tracer

R1, T, H, D = 51.68, 4.0, 3.0, 400.0  # radius, thickness, stop semi-diameter (f/17), object distance
WL = 0.5875618
Y_OBJ = 20.0


def _by_hand():
    n = float(refractive_index("N-BK7", WL))
    f = R1 / (n - 1.0)
    s = -D                                   # object distance from H (on the first vertex), sign: left negative
    s_img = 1.0 / (1.0 / f + 1.0 / s)        # 1/s' − 1/s = 1/f
    z_img = (T - T / n) + s_img              # from H' (t − t/n behind vertex 1)
    return z_img, s_img / s                  # image plane z and lateral magnification m = s'/s


def _scene(source: dict, z_det: float, side: float = 4.0):
    lens = Prescription((Surface(R1, T, "N-BK7", is_stop=True, clear_semi_diameter=H, mechanical_semi_diameter=H),
                         Surface(math.inf, 150.0, "AIR", clear_semi_diameter=H, mechanical_semi_diameter=H)),
                        Aperture("epd", 2 * H), (WL,), (1.0,), 0, (0.0,), "singlet", object_distance=D,
                        object_heights_mm=(0.0, Y_OBJ))
    # A thin front ring (it sets the front opening the source aims at) and a wide plate against the
    # lens's flat back that stops light passing around the lens (no barrel: the off-axis image lies
    # outside the lens's radius).
    mesh = TaggedMesh.concatenate([primitives.lens_elements(lens, [H, H], rings=24, segments=128),
                                   primitives.tube(-1.0, -0.5, H, H + 0.5, part="ring", finish="absorber"),
                                   primitives.tube(T, T + 0.5, H, 40.0, part="plate", finish="absorber")])
    return make_scene(lens, mesh, source=source, effects={"direct": True, "absorption": False},
                      detector={"width_mm": side, "height_mm": side, "pixels": [1, 1], "z_mm": z_det})


def _detected(scene, n, tracer=None, seed=1):
    rays, _ = scene.source.emit(n, stream(seed, "emit", 0))
    ev = (tracer or Tracer(scene)).next_event(rays)
    on = ev.kind == DETECTOR
    return ev.position[on], ev.direction[on], ev.weight[on]


def test_a_point_at_a_finite_distance_images_at_the_paraxial_conjugate_and_height():
    z_img, m = _by_hand()
    y_img = m * Y_OBJ                                # inverted: the object is at +y
    axial = _scene({"type": "point"}, z_img, side=16.0)
    tracer = Tracer(axial)                           # one mesh: the off-axis source shares the tracer
    p, d, w = _detected(axial, 15_000, tracer)
    # On axis every ray stays in its meridional plane and crosses the axis: where, against its slope u.
    # Spherical aberration moves the crossing by a u² + b u⁴; the paraxial focus is the limit u → 0.
    r = np.hypot(p[:, 0], p[:, 1])
    u = -(p[:, 0] * d[:, 0] + p[:, 1] * d[:, 1]) / np.maximum(r, 1e-12) / d[:, 2]
    keep = r > 1e-4
    z_cross = z_img + r[keep] / u[keep]
    focus = np.polyfit(u[keep] ** 2, z_cross, 2)[-1]
    assert np.ptp(z_cross) > 0.1                     # the aberration is there, and the fit removes it
    assert focus == pytest.approx(z_img, abs=0.01), (focus, z_img)
    off = _scene({"type": "point", "height_mm": Y_OBJ, "azimuth_deg": 90.0}, z_img, side=16.0)
    p, d, w = _detected(off, 15_000, tracer)
    assert len(w) > 5_000
    cy, cx = np.average(p[:, 1], weights=w), np.average(p[:, 0], weights=w)
    print(f"image plane z {z_img:.3f} mm (axial focus {focus:.4f} mm), height {y_img:.4f} mm "
          f"(m = {m:.4f}); centroid y {cy:.4f}, x {cx:.1e}")
    assert cy == pytest.approx(y_img, rel=2e-3) and abs(cx) < 1e-3


@pytest.mark.parametrize("source", [{"type": "point"}, {"type": "disc", "radius_mm": 2.0}])
def test_what_enters_the_entrance_pupil_reaches_the_image_as_the_pupil_area(source):
    """Normalisation: with the stop on surface 1 (the entrance pupil itself) and lossless glass,
    everything the source sends into the pupil lands on the image: the direct flux is A_EP."""
    z_img, m = _by_hand()
    scene = _scene(source, z_img, side=10.0)
    n = 40_000
    _, _, w = _detected(scene, n)
    area = math.pi * H * H
    frac = w.sum() / area
    # binomial noise of the share of photons that pass (most of the emission cone)
    sigma = math.sqrt(w.size * (1 - w.size / n)) / w.size * frac
    print(f"{source['type']}: direct / (flux into the entrance pupil) = {frac:.5f} ± {sigma:.5f}")
    assert frac == pytest.approx(1.0, abs=4 * sigma + 2e-3)
    assert scene.source.entering_fraction == 1.0


def test_point_source_needs_a_plane_in_front_of_the_lens():
    z_img, _ = _by_hand()
    with pytest.raises(InputError, match="not in front of surface 1"):
        _scene({"type": "point", "z_mm": 5.0}, z_img)


def test_the_ghost_analysis_asks_for_a_source_at_infinity():
    from lensmount.loop.ghosts import ghost_report

    z_img, _ = _by_hand()
    with pytest.raises(InputError, match="source at infinity"):
        ghost_report(_scene({"type": "point"}, z_img))
