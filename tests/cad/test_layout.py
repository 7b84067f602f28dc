"""Layout geometry against independent formulas, and the interference checks."""

import math

import numpy as np
import pytest

from lensmount.cad.checks import check_interference
from lensmount.templates.profile import outline
from lensmount.cad.layout import plan
from lensmount.errors import GeometryError
from lensmount.templates.spacer import Spacer


def sphere_sag(radius, h):
    """Sag of a sphere of vertex radius `radius` at height h (independent of Profile)."""
    if math.isinf(radius):
        return 0.0
    return radius - math.copysign(math.sqrt(radius * radius - h * h), radius)


def test_spacer_length_from_vertex_gap_and_sags(reference_layout):
    layout, spec = reference_layout
    p = layout.prescription
    sp = layout.part("spacer-1").template  # between lens-1 (surface 2) and lens-2 (surface 3)
    r2, r3 = p.surfaces[1].radius, p.surfaces[2].radius
    gap = p.surfaces[1].thickness  # 1.8 mm vertex gap
    hA, hB = sp.front_r, sp.back_r
    assert hA == pytest.approx(p.surfaces[1].clear_semi_diameter + spec.lens_edge.contact_margin_mm)
    assert hB == pytest.approx(p.surfaces[2].clear_semi_diameter + spec.lens_edge.contact_margin_mm)
    expected = gap + sphere_sag(r3, hB) - sphere_sag(r2, hA)
    assert sp.back_z - sp.front_z == pytest.approx(expected, abs=1e-9)


def test_every_contact_is_outside_the_clear_aperture(reference_layout):
    layout, _ = reference_layout
    assert len(layout.contacts) >= 8
    for c in layout.contacts:
        assert c.height >= c.clear


def test_diaphragm_sits_at_the_stop_with_the_stop_radius(reference_layout):
    from lensmount.cad.seats import pupil_edge_radius
    from lensmount.optics.paraxial import paraxial

    layout, spec = reference_layout
    p = layout.prescription
    d = layout.part("diaphragm").template
    assert d.z_stop == pytest.approx(p.vertex_z[5])
    # the land passes the on-axis ray entering at EPD/2 (real rays), close to the paraxial stop radius
    assert d.inner_radius == pytest.approx(pupil_edge_radius(p, d.z_stop - 0.025, d.z_stop + 0.025), abs=1e-9)
    assert d.inner_radius == pytest.approx(p.surfaces[5].clear_semi_diameter, rel=1e-3)
    # the stop radius is the marginal ray's height: paraxially EPD/2 times the pupil magnification
    assert d.inner_radius == pytest.approx(paraxial(p).stop_semi_diameter, rel=2e-3)
    assert d.land == pytest.approx(0.05)


def test_reference_has_all_parts(reference_layout):
    layout, _ = reference_layout
    names = [pp.name for pp in layout.parts]
    for n in ["barrel", "diaphragm", "hood", "housing", "retainer-1"] + [f"lens-{i}" for i in range(1, 7)]:
        assert n in names
    assert sum(n.startswith("spacer-") for n in names) == 4
    assert sum(n.startswith("vane-") for n in names) >= 3


def test_overlap_names_both_parts_and_depth():
    a = Spacer(30.0, 0.0, 0.0, 30.0, 10.0, 0.0, 33.0)
    b = Spacer(30.0, 9.5, 0.0, 30.0, 20.0, 0.0, 33.0)
    with pytest.raises(GeometryError) as exc:
        check_interference({"spacer-a": outline(a.segments()), "spacer-b": outline(b.segments())})
    text = exc.value.paragraph()
    assert "spacer-a" in text and "spacer-b" in text and "0.500 mm" in text
    touching = Spacer(30.0, 10.0, 0.0, 30.0, 20.0, 0.0, 33.0)
    check_interference({"spacer-a": outline(a.segments()), "spacer-c": outline(touching.segments())})


def test_hood_too_narrow_is_reported(reference_layout):
    layout, spec = reference_layout
    bad = spec.model_copy(update={"hood": spec.hood.model_copy(update={"inner_diameter_mm": 80.0})})
    with pytest.raises(GeometryError) as exc:
        plan(layout.prescription, bad)
    assert "hood" in exc.value.paragraph() and "beam" in exc.value.paragraph()


def test_contact_beyond_the_chamfer_is_reported(reference_layout):
    layout, spec = reference_layout
    bad = spec.model_copy(update={"lens_edge": spec.lens_edge.model_copy(update={"contact_margin_mm": 3.0})})
    with pytest.raises(GeometryError) as exc:
        plan(layout.prescription, bad)
    assert "contact height" in exc.value.paragraph()


def test_thin_diaphragm_plate_is_reported(reference_layout):
    from lensmount.cad.checks import check_thickness

    layout, spec = reference_layout
    strict = spec.model_copy(update={"checks": spec.checks.model_copy(update={"min_thickness_mm": 1.5})})
    with pytest.raises(GeometryError) as exc:
        check_thickness(layout, strict)
    assert "1.5 mm" in exc.value.paragraph()
    check_thickness(layout, spec)


def test_tangent_contact_follows_the_sphere_slope(reference_layout):
    layout, spec = reference_layout
    tangent = spec.model_copy(update={"seats": spec.seats.model_copy(update={"contact": "tangent"})})
    sp = plan(layout.prescription, tangent).part("spacer-1").template
    r3 = layout.prescription.surfaces[2].radius  # lens-2 front, convex toward the spacer
    h = sp.back_r
    # the end face follows the sphere's tangent at h: z grows outward like the glass does
    assert sp.back_slope == pytest.approx(-h / math.sqrt(r3 * r3 - h * h), rel=1e-5, abs=2e-6)
    # sharp-corner contact on the same convex surface: a flat end
    assert layout.part("spacer-1").template.back_slope == pytest.approx(0.0, abs=1e-5)


def test_envelope_never_returns_nan(monkeypatch, reference_layout):
    import lensmount.cad.plan as plan_module
    from lensmount.cad.plan import Envelope

    layout, _ = reference_layout
    monkeypatch.setattr(plan_module, "beam_envelope", lambda p, z, land=None: np.full(np.shape(z), np.nan))
    env = Envelope(layout.prescription, -10.0, 10.0, step=1.0)
    assert np.isfinite(env.at(np.linspace(-20, 20, 9))).all()
    assert np.isfinite(env.max_over(-5.0, 5.0))


def test_housing_leaves_the_detector_free(reference_layout):
    layout, spec = reference_layout
    h = layout.part("housing").template
    half_diagonal = 0.5 * math.hypot(spec.housing.detector_width_mm, spec.housing.detector_height_mm)
    assert h.inner_radius >= half_diagonal
    assert h.z_back_wall > layout.prescription.image_z
    barrel = layout.part("barrel").template
    assert h.z_front == pytest.approx(barrel.bore[-1][1])  # it starts where the barrel ends


def test_cooke_housing_is_closed_against_the_narrow_barrel(examples_dir):
    from lensmount.cad.checks import check_layout
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import load_mount

    spec = load_mount(examples_dir / "cooke-triplet" / "mount.toml")
    layout = plan(load_lens(examples_dir / "cooke-triplet" / "lens.toml"), spec)
    check_layout(layout, spec, {q.name: q.template.segments() for q in layout.parts})
    barrel, housing, hood = (layout.part(n).template for n in ("barrel", "housing", "hood"))
    assert housing.inner_radius > barrel.outer_radius  # the detector is wider than the lens
    assert housing.flange_radius is not None and housing.flange_radius < barrel.outer_radius
    assert hood.flange_radius is not None and hood.flange_radius < barrel.outer_radius


def test_the_diaphragm_is_judged_against_the_beam_its_land_passes(examples_dir):
    """The Cooke example's stop is the flint's curved rear face: the land sits 11 µm behind it at the rim,
    where the 20° beam aimed at the face's rim runs 35 µm past the land's radius (its rays leave at a
    slope of ~0.68). The land stops those rays (it is the stop); the rays it passes leave its rear end
    inside its radius, so the 45° bevel, which opens 0.76 mm per mm with the plate's cone, clears them.
    A 70° bevel opens 0.33 mm per mm: rays the land passes meet it, and the check refuses it."""
    from lensmount.cad.checks import check_beam
    from lensmount.design.lens import load_lens
    from lensmount.design.mount import load_mount
    from lensmount.optics.realrays import aim, trace

    lens = load_lens(examples_dir / "cooke-triplet" / "lens.toml")
    spec = load_mount(examples_dir / "cooke-triplet" / "mount.toml")
    layout = plan(lens, spec)
    dia = layout.part("diaphragm").template
    z0, z1, r = dia.land_range()
    o, d = aim(lens, [20.0], [[0.0, 1.0]])      # the 20° beam's upper rim ray, aimed at the stop face
    ray = trace(lens, o, d, clip=False)
    p, q = ray.points[lens.stop_index, 0], ray.points[lens.stop_index + 1, 0]
    y1 = p[1] + (z1 - p[2]) * (q[1] - p[1]) / (q[2] - p[2])
    assert y1 - r > 0.02                        # past the land: the land stops it
    check_beam(layout, {q.name: outline(q.template.segments()) for q in layout.parts})
    steep = spec.model_copy(update={"diaphragm": spec.diaphragm.model_copy(update={"bevel_angle_deg": 70.0})})
    layout = plan(lens, steep)
    with pytest.raises(GeometryError, match="diaphragm enters the beam"):
        check_beam(layout, {q.name: outline(q.template.segments()) for q in layout.parts})
