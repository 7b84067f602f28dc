"""Review: the per-process scene tables in bidirectional.py are keyed by id(scene). An id can be
reused only after its object is freed; the cache keeps a reference to the scene it describes, so a
later scene (even one allocated after the first was dropped) always gets its own tables."""

import gc
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "integrators"))
from lens_scenes import singlet_barrel  # noqa: E402

from lensmount.integrators import bidirectional  # noqa: E402
from lensmount.integrators.photon_mapping.radius import radius_caps  # noqa: E402
from lensmount.physics.bsdf import make_bsdf  # noqa: E402


def _caps(scene):
    m = scene.mesh
    return radius_caps(m.vertices, m.triangles, m.tags, len(m.tag_table))


def test_scene_tables_follow_the_scene_not_its_id():
    lam = make_bsdf("lambertian", reflectance=0.1)
    a = singlet_barrel(lam, detector_mm=20.0)
    tables_a = bidirectional._scene_tables(a)
    assert np.array_equal(tables_a[0], _caps(a))
    ids = {id(a)}
    del a
    gc.collect()
    for _ in range(5):  # fresh scenes after the first was dropped; some may land at the same address
        b = singlet_barrel(make_bsdf("lambertian", reflectance=0.2))
        b.mesh.vertices[:] = b.mesh.vertices * 1.5  # a different geometry: different face widths
        ids.add(id(b))
        hw = bidirectional._scene_tables(b)[0]
        assert np.array_equal(hw, _caps(b))
        del b
        gc.collect()
