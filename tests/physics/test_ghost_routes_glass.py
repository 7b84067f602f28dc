"""Ghost routes count the glass the tracer sees: on the example ghost scenes, with
lens.toml's `mechanical_semi_diameter` omitted (then it equals the clear semi-diameter while the
mesh's glass reaches 0.8–15 mm further) and given, the routes' two-reflection light agrees with the
photons of the same passes that made those paths (ledger `detector_ghost_routes`: the light the
routes replace), two independent codes: the routes walk the prescription's analytic surfaces out to
the faceted faces' rims (`trace.ghosts.GlassRim`); the photons go through the full tracer.

Clipping at `mechanical_semi_diameter` lost 0.43 % (Cooke) and 0.54 % (double Gauss) of the routes'
flux; the photons resolve ~15–25 % per pass here, so this comparison guards the whole channel
(coverage, walls, TIR, Fresnel weights), and `test_glass_rims_reach_the_mesh` guards the rims.
"""

import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
# the examples' ghost scenes: each in a design folder of its own (the lens and mount of double-gauss-360 and
# cooke-triplet, the coatings in its finishes.toml)
CASES = [("double-gauss-360-mgf2", "ghosts-mgf2.toml"), ("cooke-triplet-uncoated", "ghosts-uncoated.toml")]
# mechanical semi-diameter given as clear + this (mm): the double Gauss's mount puts its lens contact 0.5 mm
# beyond the clear one (a chamfer 0.5 mm short of the mechanical one), spacer-1 needs 1.85 for its wall, 3 overlaps
# lens-4 and spacer-3 (the double Gauss); 3 mm makes the Cooke's surfaces 1 and 2 cross
BEYOND_CLEAR = {"double-gauss-360-mgf2": 2.0, "cooke-triplet-uncoated": 0.5}


def _design(tmp_path, example: str, given: bool):
    """The example's design (and its ghost scene), with every glass surface's mechanical semi-diameter
    `BEYOND_CLEAR` beyond its clear one when `given`."""
    from lensmount.loop.prepare import prepare

    design = Path(shutil.copytree(EXAMPLES / example, tmp_path / example,
                                  ignore=shutil.ignore_patterns("build", ".lensmount")))
    scene_file = design / "scenes" / dict(CASES)[example]
    if given:
        scene = prepare(design, scene_file).scene
        lens = design / "lens.toml"
        blocks = re.split(r"(?m)^(?=\[\[surface\]\])", lens.read_text())
        assert len(blocks) == len(scene.optical) + 1
        for k, s in enumerate(sorted(scene.optical, key=lambda s: s.index)):
            if not np.array_equal(s.n_before, s.n_after):
                head, _, rest = blocks[k + 1].partition("\n")
                mech = s.clear_semi_diameter + BEYOND_CLEAR[example]
                blocks[k + 1] = f"{head}\nmechanical_semi_diameter = {mech:.4f}\n{rest}"
        lens.write_text("".join(blocks))
    return design, scene_file


@pytest.mark.slow
@pytest.mark.parametrize("given", [False, True], ids=["mech-omitted", "mech-given"])
@pytest.mark.parametrize("example", [c[0] for c in CASES])
def test_ghost_routes_carry_what_their_photons_do(tmp_path, example, given):
    from lensmount.integrators.estimate import film_channels
    from lensmount.integrators.forward import Forward
    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.loop.prepare import prepare
    from lensmount.trace.ghosts import glass_rims
    from lensmount.trace.tracer import Tracer

    design, scene_file = _design(tmp_path, example, given)
    scene = prepare(design, scene_file).scene
    glass = [s for s in scene.optical if not np.array_equal(s.n_before, s.n_after)]
    if given:
        beyond = BEYOND_CLEAR[example]
        assert all(s.mechanical_semi_diameter == pytest.approx(s.clear_semi_diameter + beyond, abs=1e-3) for s in glass)
    if not given:  # the case that matters: the mesh's glass reaches beyond the mechanical semi-diameter
        rims = glass_rims(scene)
        assert any(rims[s.index].radius > s.mechanical_semi_diameter + 0.5 for s in glass)
    tracer = Tracer(scene)
    ghosts = film_channels(scene).index("ghosts")
    passes = [Forward(EstimatorSettings()).run_pass(scene, tracer, i, 100_000, 11) for i in range(8)]
    routes = np.array([p.part_flux[ghosts] for p in passes])
    photons = np.array([p.ledger["detector_ghost_routes"] for p in passes])
    se = [x.std(ddof=1) / math.sqrt(len(x)) for x in (routes, photons)]
    combined = math.hypot(*se)
    print(f"\n{example} ({'given' if given else 'omitted'}): routes {routes.mean():.5g} ± {se[0]:.2g} mm², "
          f"photons {photons.mean():.5g} ± {se[1]:.2g} mm², {(routes.mean() - photons.mean()) / combined:+.2f} σ")
    # 3σ, not 1σ: a correct code sits beyond 1σ in a third of runs
    assert routes.mean() == pytest.approx(photons.mean(), abs=3 * combined)
    assert 3 * combined < 0.5 * photons.mean()  # teeth: a channel off by half fails


@pytest.mark.slow
@pytest.mark.parametrize("example", [c[0] for c in CASES])
def test_glass_rims_reach_the_mesh(tmp_path, example):
    """Every faceted face's rim holds the mesh's own triangle centres (the glass the tracer refines
    against) and no point 0.1 mm beyond its farthest vertex; the routes' lattice spans it."""
    from lensmount.loop.prepare import prepare
    from lensmount.trace.ghosts import glass_rims

    design, scene_file = _design(tmp_path, example, False)
    scene = prepare(design, scene_file).scene
    mesh, rims = scene.mesh, glass_rims(scene)
    assert rims, "no faceted glass"
    for s in scene.optical:
        tags = [k for k, t in enumerate(mesh.tag_table) if t.role == "optical" and t.surface == s.index]
        tri = mesh.triangles[np.isin(mesh.tags, tags)]
        if not len(tri):
            assert s.index not in rims
            continue
        centres = mesh.vertices[tri].mean(axis=1)[:, :2]
        assert rims[s.index].holds(centres * (1.0 - 1e-9)).all()  # a side wall's are on the rim
        far = np.hypot(*mesh.vertices[np.unique(tri)][:, :2].T).max() + 0.1
        phi = np.linspace(-math.pi, math.pi, 997)
        assert not rims[s.index].holds(far * np.column_stack([np.cos(phi), np.sin(phi)])).any()
