"""The mount realises the designed aperture: real on-axis rays traced through the lens and
tested against the mesh (Embree) find the entrance pupil the design asks for, set by the
diaphragm, on a stop plane in air (reference) and behind a curved stop face (Cooke triplet)."""

import numpy as np
import pytest

from lensmount.mesh import TaggedMesh
from lensmount.cad.pupil import realised_entrance_pupil
from lensmount.design.lens import load_lens
from lensmount.optics.paraxial import paraxial


@pytest.mark.parametrize("example", ["cooke-triplet", "double-gauss-360"])
def test_realised_entrance_pupil_is_the_designed_one(example, request):
    design, out = request.getfixturevalue("cooke")[:2] if example == "cooke-triplet" else \
        request.getfixturevalue("reference")[:2]
    p = load_lens(design / "lens.toml")
    pupil = realised_entrance_pupil(p, TaggedMesh.load(out / "mesh.npz"))
    epd = paraxial(p).epd
    assert pupil.design_diameter == pytest.approx(epd)
    assert abs(pupil.diameter / epd - 1.0) < 5e-3, (pupil.diameter, epd, set(pupil.limited_by))
    assert set(pupil.limited_by) == {"diaphragm"}


def test_the_measurement_sees_a_bore_that_limits_the_beam(reference):
    """Shrink the reference's spacer-2 bore (scale its mesh radially about the axis) into the
    on-axis beam: the measurement must report the smaller pupil and blame spacer-2."""
    design, out, _ = reference
    p = load_lens(design / "lens.toml")
    mesh = TaggedMesh.load(out / "mesh.npz")
    part = np.array([t.part for t in mesh.tag_table])[mesh.tags]
    ids = np.unique(mesh.triangles[part == "spacer-2"])
    v = mesh.vertices.copy()
    # spacer-2 runs from lens 3 to the diaphragm; its rear lip bore sits 1 mm above the beam
    v[ids, :2] *= 0.9
    shrunk = TaggedMesh(v, mesh.triangles, mesh.tags, mesh.tag_table)
    pupil = realised_entrance_pupil(p, shrunk)
    assert pupil.diameter < 0.99 * paraxial(p).epd
    assert "spacer-2" in pupil.limited_by
