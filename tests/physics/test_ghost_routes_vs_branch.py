"""The ghosts channel from deterministic ghost routes agrees with the stochastic reflection branch on the
example ghost scene (uncoated Cooke triplet, regenerated mount): same quantity, two independent codes.

The branch: photons through the full tracer (Embree mesh, the tracer's refraction, Fresnel branch with
probability R), every reflection count. The routes: sequential branching walk with the Fresnel weights,
the mount by the tracer's mechanical query, two reflections; the photons still carry four and more.
"""

import math
import shutil
from pathlib import Path

import pytest

from tests.physics.ghost_channel import ghosts_channel

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.mark.slow
def test_ghost_routes_agree_with_the_stochastic_branch_on_the_cooke_triplet(tmp_path):
    from lensmount.loop.ghosts import ghost_report
    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.loop.prepare import prepare
    from lensmount.trace.tracer import Tracer

    design = Path(shutil.copytree(EXAMPLES / "cooke-triplet-uncoated", tmp_path / "cooke-triplet",
                                  ignore=shutil.ignore_patterns("build", ".lensmount")))
    scene = prepare(design, design / "scenes" / "ghosts-uncoated.toml").scene
    tracer = Tracer(scene)
    branch, branch_se = ghosts_channel(scene, tracer, EstimatorSettings(ghost_routes=False), 200_000, 8)
    routes, routes_se = ghosts_channel(scene, tracer, EstimatorSettings(), 40_000, 6)
    print(f"\nghosts channel: branch {branch:.4g} ± {branch_se:.2g} mm², routes {routes:.4g} ± {routes_se:.2g} mm²")
    assert routes == pytest.approx(branch, abs=4 * math.hypot(branch_se, routes_se))
    # Teeth: the tolerance is below 15 %: dropping the transmittance T = 1 − R at the ~10 crossings of a
    # ghost path (×1.5) or losing the four-reflection photons' share (order 2: 1.6 %, `ghost_report`
    # order 3) in a wrong way would fail it; the routes carry a fraction of the branch's error.
    assert 4 * math.hypot(branch_se, routes_se) < 0.15 * branch and routes_se < 0.25 * branch_se
    aperture = scene.entrance_pupil_area_mm2 * scene.source.entering_fraction
    four = ghost_report(scene, tracer, 31, order=3).total_fraction - ghost_report(scene, tracer, 31).total_fraction
    assert 0.0 < four * aperture < 0.05 * branch  # what the photons still carry in the routes' run


@pytest.mark.slow
def test_ghost_routes_through_the_double_gauss_mount_carry_what_its_photons_do(tmp_path):
    """The reference double Gauss with MgF2 coatings in its regenerated mount (hood, vanes, stop plane
    the mount skips): the routes' ghosts channel against the photons of the same passes that made
    the same two-reflection paths (ledger `detector_ghost_routes`: what the routes replace), an
    independent estimate of the same light. Its rear group's first face is concave toward a stop
    plane the routes skip, so its rays start beyond that face's centre of curvature: before the
    fix of `Profile.intersect` every route missed it and the channel read 0."""
    import numpy as np

    from lensmount.integrators.estimate import film_channels
    from lensmount.integrators.forward import Forward
    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.loop.prepare import prepare
    from lensmount.trace.tracer import Tracer

    design = Path(shutil.copytree(EXAMPLES / "double-gauss-360-mgf2", tmp_path / "double-gauss-360",
                                  ignore=shutil.ignore_patterns("build", ".lensmount")))
    scene = prepare(design, design / "scenes" / "ghosts-mgf2.toml").scene
    tracer = Tracer(scene)
    ghosts = film_channels(scene).index("ghosts")
    passes = [Forward(EstimatorSettings()).run_pass(scene, tracer, i, 150_000, 11) for i in range(12)]
    routes = np.array([p.part_flux[ghosts] for p in passes])
    photons = np.array([p.ledger["detector_ghost_routes"] for p in passes])
    se = [x.std(ddof=1) / math.sqrt(len(x)) for x in (routes, photons)]
    print(f"\ndouble Gauss ghosts: routes {routes.mean():.4g} ± {se[0]:.2g} mm², photons {photons.mean():.4g} ± "
          f"{se[1]:.2g} mm²")
    assert routes.mean() == pytest.approx(photons.mean(), abs=4 * math.hypot(*se))
    assert 4 * math.hypot(*se) < 0.5 * photons.mean()  # teeth: a channel off by half fails (the photons are rare: R² a path)
