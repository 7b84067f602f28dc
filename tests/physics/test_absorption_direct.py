"""The direct image of the reference double Gauss loses what its glass absorbs, in both estimators.

With the same photons (same seed), the direct image with absorption on over the one with it off
is the flux-weighted mean, over the rays that form the image, of Π_k exp(-a_k(λ) L_k) along
each ray (six elements, 169 mm of glass on the axis). The test computes that product by hand
from sequential real rays (optics.realrays, not the tracer) and the catalogue's transmittance:
for the chief ray, and for rays across the whole pupil. A mean lies between its extremes, so the
ratio must fall inside [min, max] of the pupil's products; the chief ray's product lies in the
same band, whose width (the glass path changes across the pupil, 0.2 % here) is the tolerance.
"""

import numpy as np
import pytest

from tests.trace.geometry import double_gauss, double_gauss_mesh, make_scene
from lensmount.integrators.bidirectional import bidirectional_pass
from lensmount.integrators.forward import forward_pass
from lensmount.optics.glass import internal_transmittance
from lensmount.optics.realrays import aim, pupil_rings, trace
from lensmount.trace.tracer import Tracer

FIELD_DEG = 3.5
WL = 0.5875618


def _glass_transmittance(p, field_deg, pupil):
    """(N,) Π exp(-a L) along real rays (unclipped) at pupil points (N, 2) of one field."""
    o, d = aim(p, [field_deg], pupil, WL)
    rays = trace(p, o, d, WL, clip=False)
    out = np.ones(len(o))
    for i, s in enumerate(p.surfaces[:-1]):
        length = np.linalg.norm(rays.points[i + 1] - rays.points[i], axis=1)
        out *= internal_transmittance(s.material, WL, length)  # AIR: 1
    return out


@pytest.mark.slow
def test_direct_image_drops_by_the_glass_transmittance_along_the_chief_ray():
    p = double_gauss(wavelengths=(WL,))
    mesh = double_gauss_mesh(p)
    det = {"width_mm": 60, "height_mm": 60, "pixels": [2, 2]}  # inside the barrel: no light from around it
    src = {"type": "collimated", "off_axis_deg": FIELD_DEG, "azimuth_deg": 90.0}
    scenes = {on: make_scene(p, mesh, source=src, detector=det, effects={"direct": True, "absorption": on})
              for on in (True, False)}
    chief = float(_glass_transmittance(p, FIELD_DEG, [[0.0, 0.0]])[0])
    band = _glass_transmittance(p, FIELD_DEG, pupil_rings(8, 24))
    lo, hi = band.min(), band.max()
    assert 0.93 < chief < 0.99 and lo <= chief <= hi and hi - lo < 0.01  # a few % absorbed, a narrow band
    for name, run in (("forward", lambda s: forward_pass(s, Tracer(s), 60_000, 3, 0)),
                      ("bidirectional", lambda s: bidirectional_pass(s, Tracer(s), 60_000, 3, 0, 1.0,
                                                                     samples_per_pixel=1))):
        direct = {on: dict(zip(e.part_names, e.part_flux))["direct"] for on, e in
                  ((on, run(s)) for on, s in scenes.items())}
        assert direct[False] > 0
        ratio = direct[True] / direct[False]
        print(f"{name}: direct on/off {ratio:.5f}, chief ray {chief:.5f}, pupil band [{lo:.5f}, {hi:.5f}]")
        assert lo - 1e-9 <= ratio <= hi + 1e-9, (name, ratio, chief, lo, hi)
