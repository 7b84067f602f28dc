"""The paper's case 1 through the planner: hit points only on the
diaphragm edge, and the edge's channel the same as with every finish scattering and every effect
on. The speed ratio is `benchmarks/bench_planner.py`'s (printed here, not asserted: wall time on a
shared machine is no test)."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_planner import case1_scenes, measure  # noqa: E402

from lensmount.analysis.error_bar import t_factor  # noqa: E402
from lensmount.integrators.bidirectional import gather_cores  # noqa: E402
from lensmount.integrators.plan import plan  # noqa: E402
from lensmount.integrators.photon_mapping.view_map import build_view_map, view_map_streams  # noqa: E402
from lensmount.integrators.photon_mapping.radius import radius_caps  # noqa: E402
from lensmount.trace.tracer import Tracer  # noqa: E402


@pytest.mark.slow
def test_case1_hit_points_only_on_the_edge_and_the_edge_reads_as_with_everything_on():
    case1, everything = case1_scenes(pixels=100)
    edge = np.array([t.role == "diaphragm-edge" for t in case1.mesh.tag_table])
    p = plan(case1)
    broad = np.isfinite(gather_cores(case1.bsdf_of_tag))
    assert np.array_equal(p.scatters, edge) and np.array_equal(broad & p.scatters, edge)
    broad_on = np.isfinite(gather_cores(everything.bsdf_of_tag))
    assert (broad_on & plan(everything).scatters & ~edge).sum() > 10  # everything on: hit points all over

    # The view map itself: every hit point of a pass lies on an edge face.
    tracer = Tracer(case1)
    m = case1.mesh
    hits = build_view_map(case1, tracer, case1.detector, view_map_streams(1, 0, case1.detector, 1),
                          broad=broad & p.scatters, half_widths=radius_caps(m.vertices, m.triangles, m.tags,
                                                                             len(m.tag_table)), radius_scale=1.0)
    assert len(hits.tag) > 0 and edge[hits.tag].all()

    a = measure(case1, 0.0, 50_000, min_passes=5)
    b = measure(everything, 0.0, 50_000, seed=2, min_passes=5)  # independent photons: an honest z
    # Errors from 5 passes, widened by Student's t as the Accumulator does (t_factor): |z| < 3 is then ~99 %.
    z = (a.mean - b.mean) / math.hypot(a.std_error * t_factor(a.passes), b.std_error * t_factor(b.passes))
    print(f"\nedge channel: case 1 {a.mean:.4g} ± {a.std_error:.2g} mm² ({a.seconds / a.passes:.2f} s/pass), "
          f"everything on {b.mean:.4g} ± {b.std_error:.2g} mm² ({b.seconds / b.passes:.2f} s/pass); {z:+.2f} σ (t-widened); "
          f"photons/s to the same error: ratio {a.merit / b.merit:.2f}")
    assert a.mean > 0 and b.mean > 0 and abs(z) < 3.0
