"""The mesh plus analytic refinement is as exact as the analytic trace: a ray bundle traced
non-sequentially through the reference double Gauss lands where the sequential real-ray
trace (`optics.realrays.trace`, an independent implementation) says.

Requirement: centroid within 0.1 µm, every ray within 1e-6 mm, for three fields and three
wavelengths (dispersion), through cemented interfaces.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from tests.trace.geometry import double_gauss, double_gauss_mesh, make_scene  # noqa: E402
from lensmount.optics.glass import internal_transmittance  # noqa: E402
from lensmount.optics.paraxial import paraxial  # noqa: E402
from lensmount.optics.realrays import trace  # noqa: E402
from lensmount.physics.rays import RayBatch  # noqa: E402
from lensmount.trace.tracer import DETECTOR, Tracer  # noqa: E402


@pytest.fixture(scope="module")
def lens_and_tracer():
    p = double_gauss()
    # 5° along y images at 31.5 mm: a detector larger than the paper's 44.5 mm diagonal-field one.
    scene = make_scene(p, double_gauss_mesh(p), detector={"width_mm": 80.0, "height_mm": 80.0, "pixels": [4, 4]})
    return p, Tracer(scene)


def _bundle(p, field_deg, n, rng):
    """Rays filling 90 % of the paraxial entrance pupil at a field angle (toward +y)."""
    par = paraxial(p)
    th = np.radians(field_deg)
    d = np.array([0.0, np.sin(th), np.cos(th)])
    r = 0.45 * par.epd * np.sqrt(rng.random(n))
    ph = 2 * np.pi * rng.random(n)
    at_pupil = np.column_stack([r * np.cos(ph), r * np.sin(ph), np.full(n, par.entrance_pupil_z)])
    origin = at_pupil - (par.entrance_pupil_z + 40.0) / d[2] * d  # 40 mm in front of surface 1
    return origin, np.tile(d, (n, 1))


@pytest.mark.parametrize("field_deg", [0.0, 3.5, 5.0])
def test_bundle_lands_where_sequential_trace_says(lens_and_tracer, field_deg):
    p, tracer = lens_and_tracer
    rng = np.random.default_rng(int(field_deg * 10))
    for k, wl in enumerate(p.wavelengths_um):
        o, d = _bundle(p, field_deg, 3000, rng)
        ev = tracer.next_event(RayBatch.make(o, d, wavelength=np.full(len(o), k)), rng)
        seq = trace(p, o, d, wl)
        both = (ev.kind == DETECTOR) & ~seq.vignetted
        # The bundle is inside every clear aperture: all rays arrive in both traces.
        assert both.mean() > 0.97, (field_deg, wl, both.mean())
        landed, expected = ev.position[both], seq.points[-1][both]
        assert np.abs(landed - expected).max() < 1e-6
        assert np.linalg.norm(landed.mean(axis=0) - expected.mean(axis=0)) < 1e-4
        np.testing.assert_allclose(ev.direction[both], seq.directions[-1][both], atol=1e-9)
        # perfect AR: only the glass's bulk absorption takes light, exp(-a L) along the sequential path
        glass = np.ones(len(o))
        for i, surface in enumerate(p.surfaces[:-1]):
            length = np.linalg.norm(seq.points[i + 1] - seq.points[i], axis=1)
            glass *= internal_transmittance(surface.material, wl, length)
        assert glass[both].min() < 0.97  # 169 mm of glass on the axis: a few % absorbed
        np.testing.assert_allclose(ev.weight[both], glass[both], rtol=1e-9)


def test_dispersion_separates_colours(lens_and_tracer):
    """Blue and red chief rays at 5° land apart (lateral colour) — the index is per wavelength."""
    p, tracer = lens_and_tracer
    th = np.radians(5.0)
    d = np.array([[0.0, np.sin(th), np.cos(th)]] * 3)
    par = paraxial(p)
    o = np.array([0.0, 0.0, par.entrance_pupil_z]) - (par.entrance_pupil_z + 40.0) / d[0, 2] * d
    ev = tracer.next_event(RayBatch.make(o, d, wavelength=np.array([0, 1, 2])))
    assert np.all(ev.kind == DETECTOR)
    seq_blue = trace(p, o[1:2], d[1:2], p.wavelengths_um[1]).points[-1][0]
    assert np.abs(ev.position[1] - seq_blue).max() < 1e-6
    assert abs(ev.position[1, 1] - ev.position[2, 1]) > 1e-4


@pytest.mark.slow
def test_through_the_regenerated_cad_mesh(tmp_path):
    """The same check on the mount engineer's tessellated CAD (lens solids from STEP faces)."""
    pytest.importorskip("build123d")
    from lensmount.cad.pipeline import regenerate
    from lensmount.mesh import TaggedMesh
    from lensmount.design.lens import load_lens
    from lensmount.design.scene import scene_from_dict
    from lensmount.scene.build import build_scene
    from tests.trace.geometry import scene_dict

    design = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"
    p = load_lens(design / "lens.toml")
    manifest = regenerate(design, tmp_path)
    mesh = TaggedMesh.load(tmp_path / manifest.mesh)
    scene = build_scene(p, mesh, scene_from_dict(scene_dict(detector={"width_mm": 80.0, "height_mm": 80.0,
                                                                      "pixels": [4, 4]})))
    tracer = Tracer(scene)
    rng = np.random.default_rng(9)
    for field_deg in (0.0, 3.5):
        for k, wl in enumerate(p.wavelengths_um):
            o, d = _bundle(p, field_deg, 5000, rng)
            ev = tracer.next_event(RayBatch.make(o, d, wavelength=np.full(len(o), k)), rng)
            seq = trace(p, o, d, wl)
            both = (ev.kind == DETECTOR) & ~seq.vignetted
            assert both.mean() > 0.97
            assert np.abs(ev.position[both] - seq.points[-1][both]).max() < 1e-6


def test_even_asphere_and_conic_singlet():
    """A conic + even-asphere singlet (the Newton and conic-root paths) against the sequential trace."""
    from lensmount.optics.prescription import Aperture, Prescription, Surface
    from lensmount.scene import primitives

    p = Prescription((Surface(radius=60.0, thickness=8.0, material="SCHOTT:N-BK7", conic=-0.8,
                              aspheric=(-2e-6, 1e-9), clear_semi_diameter=15.0, mechanical_semi_diameter=15.0),
                      Surface(radius=-200.0, thickness=100.0, conic=2.0, clear_semi_diameter=15.0,
                              mechanical_semi_diameter=15.0, is_stop=True)),
                     Aperture("epd", 28.0), (0.5875618,), (1.0,), 0, (0.0,), "asphere")
    mesh = primitives.lens_elements(p, [15.0, 15.0], rings=16, segments=64)
    scene = make_scene(p, mesh, detector={"width_mm": 40.0, "height_mm": 40.0, "pixels": [1, 1]})
    tracer = Tracer(scene)
    rng = np.random.default_rng(4)
    n = 4000
    r = 14.0 * np.sqrt(rng.random(n))
    ph = 2 * np.pi * rng.random(n)
    th = np.radians(2.0)
    d = np.tile([0.0, np.sin(th), np.cos(th)], (n, 1))
    o = np.column_stack([r * np.cos(ph), r * np.sin(ph), np.zeros(n)]) - 20.0 * d
    ev = tracer.next_event(RayBatch.make(o, d))
    seq = trace(p, o, d, 0.5875618)
    both = (ev.kind == DETECTOR) & ~seq.vignetted
    assert both.mean() > 0.97
    assert np.abs(ev.position[both] - seq.points[-1][both]).max() < 1e-6
