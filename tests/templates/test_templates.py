"""Templates against closed-form volumes, tags against the analytic surfaces."""

import math
from pathlib import Path

import numpy as np
import pytest

from lensmount.cad.tessellate import tessellate_part
from lensmount.templates.diaphragm import Diaphragm
from lensmount.templates.lens_element import LensElement, OpticalFace
from lensmount.templates.profile import face_roles
from lensmount.templates.spacer import Spacer


def _cap(rho, h):
    """Volume of a spherical cap of height h on a sphere of radius rho."""
    return math.pi * h * h * (3 * rho - h) / 3


def test_biconvex_volume_is_cylinder_plus_two_caps():
    rho, a, t = 100.0, 20.0, 10.0
    el = LensElement(OpticalFace(0, 0.0, 1 / rho), OpticalFace(1, t, -1 / rho), a)
    h = rho - math.sqrt(rho * rho - a * a)
    expected = math.pi * a * a * (t - 2 * h) + 2 * _cap(rho, h)
    solid = el.build()
    assert solid.is_valid
    assert solid.volume == pytest.approx(expected, rel=1e-9)


def test_meniscus_chamfers_remove_the_corner_volume():
    """Each chamfer removes the ring between the surface, the chord and the edge: ∫ 2πr Δz dr."""
    rho1, rho2, a, t, b = 80.0, 150.0, 25.0, 8.0, 0.5
    plain = LensElement(OpticalFace(0, 0.0, 1 / rho1), OpticalFace(1, t, 1 / rho2), a)
    cham = LensElement(OpticalFace(0, 0.0, 1 / rho1), OpticalFace(1, t, 1 / rho2), a, b, b)
    vp, vc = plain.build().volume, cham.build().volume
    # each chamfer cuts the corner between the surface and the edge cylinder; the cut is
    # bounded by the 45° line, the cylinder and the sphere: integrate it numerically in r
    r = np.linspace(a - b, a, 20001)
    s1 = rho1 - np.sqrt(rho1**2 - r**2)
    s2 = t + rho2 - np.sqrt(rho2**2 - r**2)
    def chord(z0, z1):  # the chamfer: from the surface at a - b to the edge, b inside
        return z0 + (z1 - z0) * (r - (a - b)) / b
    line1 = chord(s1[0], s1[-1] + b)
    line2 = chord(s2[0], s2[-1] - b)
    cut = np.trapezoid(2 * np.pi * r * ((line1 - s1) + (s2 - line2)), r)
    assert vp - vc == pytest.approx(cut, rel=1e-5)


def test_flat_spacer_is_an_annulus():
    sp = Spacer(30.0, 10.0, 0.0, 30.0, 25.0, 0.0, 33.0)
    assert sp.build().volume == pytest.approx(math.pi * (33.0**2 - 30.0**2) * 15.0, rel=1e-9)


def test_spacer_tube_volume():
    sp = Spacer(30.0, 0.0, 0.0, 30.0, 50.0, 0.0, 36.0, tube_radius=34.0, lip=2.0)
    expected = math.pi * (36.0**2 - 34.0**2) * 50.0 + 2 * math.pi * (34.0**2 - 30.0**2) * 2.0
    assert sp.build().volume == pytest.approx(expected, rel=1e-9)


def test_lens_tags_lie_on_the_analytic_surfaces():
    rho1, rho2, a = 60.0, -90.0, 18.0
    front, back = OpticalFace(4, 100.0, 1 / rho1), OpticalFace(5, 109.0, 1 / rho2)
    el = LensElement(front, back, a, 0.4, 0.4)
    solid = el.build()
    roles = face_roles(solid, el.segments())
    assert sorted(r for r, _ in roles) == ["bevel", "bevel", "lens-edge", "optical", "optical"]
    mesh = tessellate_part(solid, "lens-x", "lens", "ground-glass", roles, 0.05, 6.0)
    for tag_id, tag in enumerate(mesh.tag_table):
        v = mesh.vertices[np.unique(mesh.triangles[mesh.tags == tag_id])]
        r = np.hypot(v[:, 0], v[:, 1])
        if tag.role == "optical":
            f = front if tag.surface == 4 else back
            assert tag.surface in (4, 5)
            np.testing.assert_allclose(v[:, 2], f.z(r), atol=1e-7)
        elif tag.role == "lens-edge":
            np.testing.assert_allclose(r, a, atol=1e-7)
        elif tag.role == "bevel":
            assert r.min() >= a - 0.4 - 1e-7


def test_a_deep_face_and_its_flat_bevel_are_tagged_optical_and_bevel():
    """A deep concave face (R -85 mm out to 64 mm: 49° of arc, 29 mm of sag) with a flat bevel out to a
    90 mm rim: every profile segment is one CAD face, and each face is tagged with its segment's role,
    not `mount` (a face tagged `mount` absorbs the light as metal would)."""
    front, back = OpticalFace(10, 193.87, -1 / 85.2817), OpticalFace(11, 205.831, 1 / 584.8597)
    el = LensElement(front, back, 90.4, 0.1, 0.1, front_flat_from=64.229)
    solid = el.build()
    roles = face_roles(solid, el.segments())
    assert sorted(roles) == sorted((s.role, s.surface) for s in el.segments() if not s.on_axis())
    assert ("optical", 10) in roles and ("mount", -1) not in roles


def test_diaphragm_edge_land_width():
    d = Diaphragm(150.0, 16.3, 31.0, 1.0, 0.05, 45.0, "rear")
    solid = d.build()
    roles = face_roles(solid, d.segments())
    mesh = tessellate_part(solid, "diaphragm", "diaphragm", "black-anodised", roles, 0.05, 6.0)
    edge = [i for i, t in enumerate(mesh.tag_table) if t.role == "diaphragm-edge"]
    assert len(edge) == 1
    v = mesh.vertices[np.unique(mesh.triangles[mesh.tags == edge[0]])]
    np.testing.assert_allclose(np.hypot(v[:, 0], v[:, 1]), 16.3, atol=1e-7)
    assert v[:, 2].max() - v[:, 2].min() == pytest.approx(0.05, abs=1e-9)
    assert 0.5 * (v[:, 2].max() + v[:, 2].min()) == pytest.approx(150.0, abs=1e-9)


def test_asphere_spline_face_follows_the_sag():
    """Conic + even-asphere faces are splines through sag samples: volume and mesh on the surface."""
    from lensmount.optics.profiles import Profile

    front = OpticalFace(0, 0.0, 1 / 40.0, -0.6, (2e-6,))
    back = OpticalFace(1, 9.0, -1 / 120.0)
    a = 15.0
    el = LensElement(front, back, a)
    solid = el.build()
    assert solid.is_valid
    r = np.linspace(0.0, a, 200001)
    thickness = back.z(r) - front.z(r)
    assert solid.volume == pytest.approx(np.trapezoid(2 * np.pi * r * thickness, r), rel=1e-5)
    roles = face_roles(solid, el.segments())
    mesh = tessellate_part(solid, "asph", "lens", "ground-glass", roles, 0.02, 5.0)
    k = [i for i, t in enumerate(mesh.tag_table) if t.role == "optical" and t.surface == 0]
    v = mesh.vertices[np.unique(mesh.triangles[np.isin(mesh.tags, k)])]
    sag = Profile(1 / 40.0, -0.6, (2e-6,)).sag(v[:, 0] ** 2 + v[:, 1] ** 2)
    assert np.abs(v[:, 2] - sag).max() < 1e-4  # the tracer refines hits analytically anyway


def test_steep_q_type_face_is_tagged_optical_and_follows_its_sag():
    """Thorlabs' ASL5040-UV: a Qbfs face 20 mm deep over its 24 mm rim. Its solid is valid, the face is
    `optical` surface 0 (its 41 sag samples' chords lie 5.6e-3 mm inside it, more than face_roles'
    1e-3 mm: matched against the cubic the solid interpolates) and its mesh lies on the Q-type sag."""
    from pathlib import Path

    from lensmount.optics.io.zemax import read_zmx
    from lensmount.optics.profiles import Profile

    p = read_zmx(Path(__file__).parents[1] / "optics" / "corpus" / "thorlabs-ASL5040-UV-qbfs-utf16.zmx")
    el = LensElement(OpticalFace.of(0, 0.0, p.surfaces[0]), OpticalFace.of(1, p.vertex_z[1], p.surfaces[1]),
                     24.0, 0.1, 0.1)
    solid = el.build()
    assert solid.is_valid
    roles = face_roles(solid, el.segments())
    assert ("optical", 0) in roles and ("optical", 1) in roles
    mesh = tessellate_part(solid, "asl", "lens", "ground-glass", roles, 0.02, 5.0)
    k = [i for i, t in enumerate(mesh.tag_table) if t.role == "optical" and t.surface == 0]
    v = mesh.vertices[np.unique(mesh.triangles[np.isin(mesh.tags, k)])]
    assert np.hypot(v[:, 0], v[:, 1]).max() > 23.0
    assert np.abs(v[:, 2] - Profile.of(p.surfaces[0]).sag(v[:, 0] ** 2 + v[:, 1] ** 2)).max() < 1e-3


def test_a_steep_aspheres_face_is_tagged_optical():
    """Thorlabs ACL25416U-A's front face (R 8.818 mm, k -0.99917, A4..A8; tests/optics/corpus): its
    spline through the sag samples strays ~3 µm from their chords at the 12.7 mm rim, more than the
    1 µm match tolerance, and the optical face was tagged as metal ('mount'): the realised pupil was
    nil and the tracer would have scattered the light off the glass."""
    front = OpticalFace(0, 0.0, 1.0 / 8.818196517367504, -0.9991715230203,
                        (8.68216737142e-05, 6.376012336251e-08, 2.407308400812e-09))
    back = OpticalFace(1, 14.0, 1.0 / -69.99948216040457)
    el = LensElement(front, back, 13.462, 0.5, 0.5)
    roles = face_roles(el.build(), el.segments())
    assert ("optical", 0) in roles and ("optical", 1) in roles


@pytest.fixture(scope="module")
def reference_layout():
    """Layout of the reference lens with the reference mount (no CAD kernel)."""
    from lensmount.cad.layout import plan
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import load_mount

    example = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"
    spec = load_mount(example / "mount.toml")
    return plan(load_lens(example / "lens.toml"), spec), spec


def test_a_built_in_part_whose_faces_are_not_all_recognised_is_refused(reference_layout, monkeypatch):
    """Were the face matching to miss a face of a built-in part (here: every face looked up far off), the
    part is refused with its name, not built with a glass face tagged `mount` (absorbing as metal)."""
    from dataclasses import replace

    from lensmount.cad.assembly import build_parts
    from lensmount.errors import GeometryError
    from lensmount.templates import profile

    layout, spec = reference_layout
    one = replace(layout, parts=[layout.part("lens-1")])
    assert [bp.plan.name for bp in build_parts(one, spec)] == ["lens-1"]
    monkeypatch.setattr(profile, "_profile_point", lambda face: np.array([1e4, 1e4]))
    with pytest.raises(GeometryError, match="lens-1: .* not found on the solid"):
        build_parts(one, spec)
