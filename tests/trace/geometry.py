"""Test geometry built without the CAD layer: the reference double Gauss as revolved glass
solids, a barrel, enclosures, and a scene spec in code.

The prescription is typed from /work/shared/reference/double-gauss-360.md (radii ×3.6
applied). Semi-diameters here are the test's own choice (paraxial marginal height at f/7
plus a field allowance), not the optics engineer's automatic apertures.
"""

from __future__ import annotations

import math

from lensmount.mesh import TaggedMesh
from lensmount.design.scene import scene_from_dict
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.scene import primitives
from lensmount.scene.build import build_scene

INF = math.inf

DOUBLE_GAUSS_ROWS = [  # radius, thickness, material, is_stop
    (202.328568, 31.5, "SCHOTT:N-SSK2", False),
    (548.22888, 1.8, "AIR", False),
    (135.657432, 45.0, "SCHOTT:N-SK2", False),
    (INF, 13.68, "SCHOTT:F5", False),
    (87.23268, 58.930002, "AIR", False),
    (INF, 49.4926452, "AIR", True),
    (-102.158316, 13.68, "SCHOTT:F5", False),
    (INF, 39.6, "SCHOTT:N-SK16", False),
    (-136.531656, 1.8, "AIR", False),
    (638.682336, 25.2, "SCHOTT:N-SK16", False),
    (-285.881148, 221.3551296, "AIR", False),
]
# Semi-diameters (mm): on-axis f/7 bundle plus room for the ±5° field.
DOUBLE_GAUSS_SD = [46.0, 44.0, 40.0, 38.0, 34.0, 31.0, 33.0, 38.0, 40.0, 43.0, 43.0]


def double_gauss(scale: float = 1.0, wavelengths=(0.5875618, 0.4861327, 0.6562725)) -> Prescription:
    """The reference lens, optionally scaled (a 5 mm or 2 m version for the stability suite)."""
    surfaces = []
    for (r, t, m, stop), sd in zip(DOUBLE_GAUSS_ROWS, DOUBLE_GAUSS_SD):
        surfaces.append(Surface(radius=r * scale, thickness=t * scale, material=m, is_stop=stop,
                                clear_semi_diameter=sd * scale * 0.95, mechanical_semi_diameter=sd * scale))
    return Prescription(tuple(surfaces), Aperture("fno", 7.0), tuple(wavelengths),
                        tuple([1.0] * len(wavelengths)), 0, (0.0, 3.5, 5.0), "double-gauss-360")


def double_gauss_mesh(p: Prescription, *, rings: int = 24, segments: int = 96, barrel: bool = True) -> TaggedMesh:
    """Glass solids of every group, plus an absorbing barrel tube and a diaphragm at the stop."""
    scale = p.surfaces[0].radius / DOUBLE_GAUSS_ROWS[0][0]
    sds = [s.mechanical_semi_diameter for s in p.surfaces]
    parts = [primitives.lens_elements(p, sds, rings=rings, segments=segments)]
    if barrel:
        zs = p.vertex_z
        r_in = max(sds) + 0.5 * scale
        parts.append(primitives.tube(-20.0 * scale, zs[-1] + 30.0 * scale, r_in, r_in + 5.0 * scale))
        stop = p.stop_index
        parts.append(primitives.tube(zs[stop] - 0.025 * scale, zs[stop] + 0.025 * scale, 0.5 * 51.43 * scale * 0.66,
                                     r_in, part="diaphragm", kind="diaphragm", finish="black-anodised"))
    return TaggedMesh.concatenate(parts)


def scene_dict(**over) -> dict:
    base = {
        "description": "test",
        "source": {"type": "sun", "off_axis_deg": 0.0, "azimuth_deg": 90.0},
        "detector": {"width_mm": 44.5, "height_mm": 44.5, "pixels": [8, 8]},
        "effects": {"scatter": True, "ghosts": False, "direct": True},
        "assign": {"*": "absorber"},
    }
    for k, v in over.items():
        base[k] = v
    return base


def make_scene(p: Prescription, mesh: TaggedMesh, **over):
    return build_scene(p, mesh, scene_from_dict(scene_dict(**over)))


def air_plane() -> Prescription:
    """A prescription with one plane air-air surface: scenes with no glass."""
    return Prescription((Surface(thickness=100.0, clear_semi_diameter=10.0, mechanical_semi_diameter=10.0),),
                        Aperture("epd", 10.0))


def window(thickness: float = 5.0, glass: str = "SCHOTT:N-BK7", semi_diameter: float = 20.0) -> Prescription:
    """A plane-parallel glass plate at z = 0 (a window), image plane 50 mm behind it."""
    s = dict(clear_semi_diameter=semi_diameter, mechanical_semi_diameter=semi_diameter)
    return Prescription((Surface(thickness=thickness, material=glass, **s), Surface(thickness=50.0, **s)),
                        Aperture("epd", 2 * semi_diameter))


def mech_scene(mesh: TaggedMesh, *, detector=None, **over):
    """A scene of mechanical parts only (no glass), detector far away unless given."""
    det = detector or {"width_mm": 1.0, "height_mm": 1.0, "pixels": [1, 1], "z_mm": 1.0e4}
    return make_scene(air_plane(), mesh, detector=det, **over)
