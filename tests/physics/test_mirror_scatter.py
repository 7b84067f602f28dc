"""A mirror with a scatter finish: specular R(1 − a), scattered R·a by the finish's BSDF.

References are analytic and independent of the code under test: the Lambertian albedo ρ, the
ABg lobe with g = 2 (TIS = πA ln(1 + 1/B), ring masses πA ln((B + ρ2²)/(B + ρ1²))), binomial
and Monte Carlo standard errors; the forward estimator is the bidirectional's reference.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.physics.ghost_channel import ghosts_channel  # noqa: E402
from tests.trace.geometry import make_scene  # noqa: E402

from lensmount.mesh import FaceTag, TaggedMesh  # noqa: E402
from lensmount.errors import InputError  # noqa: E402
from lensmount.integrators.bidirectional import bidirectional_pass  # noqa: E402
from lensmount.integrators.estimate import EnergyLedger, Film, ledger_residual  # noqa: E402
from lensmount.integrators.forward import forward_pass  # noqa: E402
from lensmount.integrators.plan import plan  # noqa: E402
from lensmount.integrators.settings import EstimatorSettings  # noqa: E402
from lensmount.integrators.walk import emit_photons, photon_walk  # noqa: E402
from lensmount.optics.prescription import Aperture, Prescription, Surface  # noqa: E402
from lensmount.optics.profiles import Profile  # noqa: E402
from lensmount.scene import primitives  # noqa: E402
from lensmount.scene.primitives import _cap  # noqa: E402
from lensmount.physics.rays import RayBatch  # noqa: E402
from lensmount.physics.sampler import Streams  # noqa: E402
from lensmount.trace.tracer import FACE, GONE, MIRROR_SCATTER_MIN_SHARE, Tracer  # noqa: E402

FAR = {"width_mm": 1.0, "height_mm": 1.0, "pixels": [1, 1], "z_mm": 1.0e4}  # behind the mirror: nothing lands


def _flat_mirror(finish: dict | None, reflectance: float, **scene):
    """A flat front-surface mirror at z = 0 (60 mm, light from −z returns to −z) given `finish` by "surface:1"."""
    m = Surface(radius=math.inf, thickness=-100.0, mirror=True, is_stop=True, clear_semi_diameter=30.0,
                mechanical_semi_diameter=30.0, coating=f"R={reflectance}")
    p = Prescription((m,), Aperture("epd", 60.0))
    v, t = _cap(Profile.of(m), 0.0, 30.0, 8, 32)
    mesh = TaggedMesh(v, t, np.zeros(len(t), np.int32), [FaceTag("mirror-1", "mirror", "optical", "polished",
                                                                 surface=0, face=0)])
    assign = {"*": "absorber"} | ({"surface:1": "finish"} if finish else {})
    return make_scene(p, mesh, detector=FAR, finishes={"finish": finish} if finish else {}, assign=assign, **scene)


def _abg(tis: float, b: float = 0.01) -> dict:
    """ABg with g = 2 whose TIS (πA ln(1 + 1/B)) is `tis`."""
    return {"model": "abg", "A": tis / (math.pi * math.log1p(1.0 / b)), "B": b, "g": 2.0}


def _beam(n: int, incidence_deg: float):
    """n parallel rays over the mirror's centre at `incidence_deg` in the y–z plane, from z = −50."""
    th = math.radians(incidence_deg)
    rng = np.random.default_rng(11)
    xy = rng.uniform(-10.0, 10.0, (n, 2))
    o = np.column_stack([xy[:, 0], xy[:, 1] - 50.0 * math.tan(th), np.full(n, -50.0)])
    return o, np.tile([0.0, math.sin(th), math.cos(th)], (n, 1))


def _events_at_a_lambertian_mirror(n: int, rho: float, r: float, incidence_deg: float, seed: int):
    """(scene, (origins, directions), events) of `_beam` on a flat mirror of reflectance r whose
    finish is Lambertian with albedo rho."""
    scene = _flat_mirror({"model": "lambertian", "reflectance": rho}, r)
    o, d = _beam(n, incidence_deg)
    return scene, (o, d), Tracer(scene).next_event(RayBatch.make(o, d), Streams(seed, "mirror", np.arange(n)))


def _within(observed: float, expected: float, sigma: float, k: float = 4.0) -> bool:
    return abs(observed - expected) <= k * sigma


def test_a_mirror_with_a_finish_ends_a_share_a_on_its_face_and_reflects_the_rest_specularly_both_with_r():
    n, rho, r = 20_000, 0.3, 0.9
    scene, (o, d), ev = _events_at_a_lambertian_mirror(n, rho, r, 30.0, 5)
    at_face = ev.kind == FACE
    assert _within(at_face.mean(), rho, math.sqrt(rho * (1 - rho) / n))
    np.testing.assert_allclose(ev.weight, r, rtol=1e-12)  # both branches carry R: R(1 − a) + R·a on average
    assert np.all(ev.tag[at_face] == 0) and np.all(ev.prim[at_face] >= 0)
    np.testing.assert_allclose(ev.normal[at_face], np.tile([0.0, 0.0, -1.0], (at_face.sum(), 1)), atol=1e-12)
    np.testing.assert_allclose(ev.direction[at_face], d[at_face], atol=1e-12)  # the arriving direction
    np.testing.assert_allclose(ev.position[at_face, 2], 0.0, atol=1e-9)
    spec = ~at_face
    assert np.all(ev.kind[spec] == GONE)
    np.testing.assert_allclose(ev.direction[spec], d[spec] * [1.0, 1.0, -1.0], atol=1e-12)
    # without numbers (geometric callers) the mirror stays specular
    plain = Tracer(scene).next_event(RayBatch.make(o, d))
    assert np.all(plain.kind == GONE)


def test_a_polished_mirror_scatters_a_tenth_of_its_rays_weighted_to_keep_r_a_scattered_and_r_one_minus_a_specular():
    # TIS 1e-2 (dust): p = 0.1 of the rays take the finish with weight R·a/p, the others R(1 − a)/(1 − p)
    n, rho, r = 20_000, 0.01, 0.9
    _, _, ev = _events_at_a_lambertian_mirror(n, rho, r, 20.0, 9)
    at_face = ev.kind == FACE
    p = MIRROR_SCATTER_MIN_SHARE
    assert _within(at_face.mean(), p, math.sqrt(p * (1 - p) / n))
    np.testing.assert_allclose(ev.weight[at_face], r * rho / p, rtol=1e-12)
    np.testing.assert_allclose(ev.weight[~at_face], r * (1 - rho) / (1 - p), rtol=1e-12)
    scattered, specular = np.where(at_face, ev.weight, 0.0), np.where(at_face, 0.0, ev.weight)
    assert _within(scattered.mean(), r * rho, scattered.std() / math.sqrt(n))
    assert _within(specular.mean(), r * (1 - rho), specular.std() / math.sqrt(n))


def _walk(scene, n: int, seed: int = 3):
    """Per bounce (ids, directions, fluxes) of the photons leaving the scene, Φ0 (each photon's emitted
    flux) and the ledger; at bounce 0 only those the mirror sent back (−z: the emission disc is wider
    than the mirror, and what misses it leaves along +z)."""
    film, ledger = Film(scene), EnergyLedger()
    rays = emit_photons(scene, seed, "mirror-test", 0, n, n)
    phi0 = float(rays.weight[rays.alive][0])
    out = []
    for bounce in photon_walk(scene, Tracer(scene), rays, seed, "mirror-test", EstimatorSettings(), film, ledger):
        ev = bounce.events
        gone = (ev.kind == GONE) & ~ev.lost & ((ev.direction[:, 2] < 0.0) | (len(out) > 0))
        out.append((ev.id[gone], ev.direction[gone], ev.weight[gone]))
    assert film.faces.finish().lit[0] == 0.0  # a mirror's face is left out of the faces report
    return out, phi0, ledger


def test_white_furnace_a_perfect_mirror_returns_everything_split_one_minus_tis_specular_and_tis_scattered():
    n, tis = 40_000, 0.25
    scene = _flat_mirror(_abg(tis), 1.0, source={"type": "collimated", "off_axis_deg": 0.0, "azimuth_deg": 90.0})
    steps, phi0, ledger = _walk(scene, n)
    assert len(steps) == 2  # light leaves straight away or after one scatter at the mirror
    (id0, d0, w0), (id1, d1, w1) = steps
    hit = len(id0) + len(id1)  # photons on the mirror
    np.testing.assert_allclose(d0[:, 2], -1.0, atol=1e-12)  # specular: straight back
    np.testing.assert_allclose(w0, phi0, rtol=1e-12)
    assert _within(len(id1) / hit, tis, math.sqrt(tis * (1 - tis) / hit))  # the scattered share, TIS at 0°
    # scattered energy: R · lobe weight, mean 1 (the finish's albedo over itself); total = R = 1
    per_photon = np.concatenate([w0, w1]) / phi0
    assert _within(per_photon.mean(), 1.0, per_photon.std() / math.sqrt(hit) + 1e-12)
    entries = ledger.as_dict()
    assert entries["escaped"] == pytest.approx(entries["source"], rel=5.0 * per_photon.std() / math.sqrt(hit))
    assert abs(ledger_residual(entries)) < 1e-12


def test_the_scattered_lobe_follows_the_finishs_brdf_ring_by_ring():
    # ABg g = 2 at normal incidence: flux into the ring ρ1 < |β| < ρ2 of direction cosines per photon
    # on the mirror is R · πA ln((B + ρ2²)/(B + ρ1²)) (cosθ dω = d²β)
    n, tis, b, r = 60_000, 0.4, 0.01, 0.8
    finish = _abg(tis, b)
    scene = _flat_mirror(finish, r, source={"type": "collimated", "off_axis_deg": 0.0, "azimuth_deg": 90.0})
    ((id0, _, _), (id1, d1, w1)), phi0, _ = _walk(scene, n)
    hit = len(id0) + len(id1)
    beta = np.hypot(d1[:, 0], d1[:, 1])
    edges = np.array([0.0, 0.02, 0.05, 0.1, 0.2, 0.4, 0.7, 1.0])
    for lo, hi in zip(edges[:-1], edges[1:]):
        x = np.where((beta >= lo) & (beta < hi), w1 / phi0, 0.0)
        x = np.concatenate([x, np.zeros(hit - len(x))])  # every photon on the mirror, scattered or not
        expected = r * math.pi * finish["A"] * math.log((b + hi * hi) / (b + lo * lo))
        assert _within(x.mean(), expected, x.std() / math.sqrt(hit)), (lo, hi, x.mean(), expected)


def test_a_finish_is_given_only_to_a_mirror_surface_and_is_not_itself_a_mirror():
    m = Surface(radius=math.inf, thickness=-100.0, mirror=True, is_stop=True, clear_semi_diameter=30.0,
                mechanical_semi_diameter=30.0)
    p = Prescription((m,), Aperture("epd", 60.0))
    v, t = _cap(Profile.of(m), 0.0, 30.0, 4, 16)
    mesh = TaggedMesh(v, t, np.zeros(len(t), np.int32), [FaceTag("mirror-1", "mirror", "optical", "polished",
                                                                 surface=0, face=0)])
    with pytest.raises(InputError, match="names no mirror surface") as err:
        make_scene(p, mesh, detector=FAR, assign={"*": "absorber", "surface:2": "black-anodised"})
    assert "surface:N for the mirror surfaces 1" in err.value.paragraph()
    with pytest.raises(InputError, match="does not name a surface number"):
        make_scene(p, mesh, detector=FAR, assign={"surface:primary": "black-anodised"})
    with pytest.raises(InputError, match="already reflects specularly"):
        make_scene(p, mesh, detector=FAR, assign={"*": "absorber", "surface:1": "mirror"})
    # "*" does not reach the coated face; "surface:1" does, and a scatter selector names it
    assert make_scene(p, mesh, detector=FAR, assign={"*": "black-anodised"}).bsdf_of_tag == [None]
    scene = make_scene(p, mesh, detector=FAR, assign={"surface:1": "black-anodised"},
                       effects={"scatter": ["surface:1"], "ghosts": False, "direct": False})
    assert scene.bsdf_of_tag[0].finish.tis == pytest.approx(0.05)
    assert [d.ran for d in plan(scene).decisions if d.what.startswith("scatter at mirror")] == [True]
    with pytest.raises(InputError, match="names no face"):
        make_scene(p, mesh, detector=FAR, assign={"surface:1": "black-anodised"},
                   effects={"scatter": ["surface:2"], "ghosts": False, "direct": False})
    for selector, scatters in (("part:mirror-1", True), ("kind:mirror", True), ("finish:black-anodised", True),
                               ("finish:polished", False)):  # finish: the scene's, not the mount's
        with_face = make_scene(p, mesh, detector=FAR, assign={"surface:1": "black-anodised"},
                               objects=[{"type": "disk", "name": "plate", "centre_mm": [0.0, 0.0, -80.0],
                                         "radius_mm": 5.0, "finish": "polished"}],
                               finishes={"polished": {"model": "lambertian", "reflectance": 0.5}},
                               effects={"scatter": [selector], "ghosts": False, "direct": False})
        assert [d.ran for d in plan(with_face).decisions if d.what.startswith("scatter at mirror")] == [scatters]


def _tube(z0: float, z1: float, r_inner: float, r_outer: float) -> TaggedMesh:
    """`primitives.tube` with one tag per wall (front end, outside, back end, bore), as the CAD tags
    faces: a gather's area is measured on its face, and four walls in one tag would blur it."""
    m = primitives.tube(z0, z1, r_inner, r_outer, part="tube", kind="baffle", finish="baffle")
    wall = np.repeat(np.arange(4, dtype=np.int32), len(m.triangles) // 4)  # 2 triangles per segment per wall
    return TaggedMesh(m.vertices, m.triangles, wall, [FaceTag("tube", "baffle", "mount", "baffle", face=k)
                                                      for k in range(4)])


def _cassegrain(finish: dict | None, off_axis_deg: float = 1.0, baffle: float = 0.5, direct: bool = True,
                tube_from: float = -20.0):
    """A small Cassegrain (f = 333 mm, f/5.6): concave primary R −200 (30 mm, 7.5 mm hole), convex
    secondary R −85.7 70 mm in front of it (10 mm, its back an absorbing disc), both R = 0.9, a central
    baffle tube (Lambertian `baffle`, z `tube_from` … −0.5 mm, bore 7.6 mm: from −20 the image beam of a
    source 1° off axis clears it by 0.2 mm; from −40 it lights its front end) in front of the hole, the
    image 30 mm behind the primary; the primary's coated face given `finish`."""
    primary = Surface(radius=-200.0, thickness=-70.0, mirror=True, is_stop=True, clear_semi_diameter=30.0,
                      mechanical_semi_diameter=30.0, coating="R=0.9")
    secondary = Surface(radius=-600.0 / 7.0, thickness=100.0, mirror=True, clear_semi_diameter=10.0,
                        mechanical_semi_diameter=10.0, coating="R=0.9")
    p = Prescription((primary, secondary), Aperture("epd", 60.0))
    zs = p.vertex_z
    v1, t1 = _cap(Profile.of(primary), zs[0], 30.0, 16, 64)
    t1 = t1[64:]  # without the central fan: the hole, a quarter of the radius
    v2, t2 = _cap(Profile.of(secondary), zs[1], 10.0, 6, 48)
    mirrors = TaggedMesh(np.vstack([v1, v2]), np.vstack([t1, t2 + len(v1)]),
                         np.concatenate([np.zeros(len(t1), np.int32), np.ones(len(t2), np.int32)]),
                         [FaceTag("mirror-1", "mirror", "optical", "polished", surface=0, face=0),
                          FaceTag("mirror-2", "mirror", "optical", "polished", surface=1, face=0)])
    mesh = TaggedMesh.concatenate([mirrors, primitives.disk((0.0, 0.0, zs[1] - 1.0), 10.5, part="spider"),
                                   _tube(tube_from, -0.5, 7.6, 8.6)])
    finishes = {"baffle": {"model": "lambertian", "reflectance": baffle}} | ({"dust": finish} if finish else {})
    assign = {"*": "absorber", "part:tube": "baffle"} | ({"surface:1": "dust"} if finish else {})
    return make_scene(p, mesh, detector={"width_mm": 12.0, "height_mm": 12.0, "pixels": [8, 8], "z_mm": 30.0},
                      source={"type": "collimated", "off_axis_deg": off_axis_deg, "azimuth_deg": 90.0},
                      finishes=finishes, assign=assign, effects={"scatter": True, "ghosts": False, "direct": direct})


def test_a_finish_with_no_scatter_gives_exactly_the_run_without_one():
    # TIS = 0: the tracer draws its branch number but never takes it; same seed, same photons, same image
    plain, dusty = _cassegrain(None, 1.0), _cassegrain({"model": "lambertian", "reflectance": 0.0}, 1.0)
    assert "mirror-1" in plan(dusty).decisions[1].what
    for run in (lambda s: forward_pass(s, Tracer(s), 10_000, 7, 2),
                lambda s: bidirectional_pass(s, Tracer(s), 10_000, 7, 2, 1.0)):
        a, b = run(plain), run(dusty)
        assert a.flux > 0.0
        np.testing.assert_array_equal(a.image, b.image)
        assert a.ledger == {k: v for k, v in b.ledger.items() if v != 0.0 or k in a.ledger}


@pytest.mark.slow  # ~30 s each on the loaded 2-core machine
@pytest.mark.parametrize("finish, resolved", [(_abg(0.3, 0.01), (20.0, 3.0)),
                                              ({"model": "lambertian", "reflectance": 0.3}, (5.0, 0.0))],
                         ids=["micro-roughness", "dust"])
def test_forward_and_bidirectional_agree_on_a_cassegrain_whose_primary_scatters(finish, resolved):
    # The primary's scatter is the main stray path (primary → secondary → hole → detector), counted
    # by photons in both estimators (independent streams); the baffle tube's light (the primary's
    # scatter → secondary → tube → detector) is gathered by the bidirectional one. Micro-roughness
    # (ABg, TIS 0.3, 5.7° half width) is a halo around the image; dust (Lambertian 0.3) a broad lobe,
    # which a gather at hit points on the mirror would have counted at ~a·R of its value (0.07 for
    # 0.26: the tracer's branch thins both the hit points and the photons there). Each channel and
    # the total agree within 3 combined standard errors (batch means over 8 passes).
    scene = _cassegrain(finish, 1.0, baffle=0.9, direct=False)
    tracer = Tracer(scene)
    runs = {}
    for method in ("forward", "bidirectional"):
        flux = []
        for i in range(8):
            est = (forward_pass(scene, tracer, 100_000, 1, i) if method == "forward" else
                   bidirectional_pass(scene, tracer, 100_000, 1, i, 1.0, samples_per_pixel=16))
            assert est.part_names == ["mirror-1", "tube"]
            flux.append(np.append(est.part_flux, est.flux))
        flux = np.array(flux)
        assert np.all(np.isfinite(flux))
        runs[method] = (flux.mean(axis=0), flux.std(axis=0, ddof=1) / math.sqrt(len(flux)))
    (mf, sf), (mb, sb) = runs["forward"], runs["bidirectional"]
    assert mf[0] > resolved[0] * sf[0] and mf[1] >= resolved[1] * sf[1]  # resolved, not noise
    assert np.all(np.abs(mf - mb) <= 3.0 * np.hypot(sf, sb)), (mf, sf, mb, sb)


@pytest.mark.slow  # ~12 s
def test_the_ghost_routes_carry_only_the_specular_share_of_a_scattering_mirror():
    # an uncoated BK7 window in front of the Cassegrain: its two-reflection ghost reaches the detector
    # by the primary, whose micro-roughness (TIS 0.3) sends a share a of it to the photons. The
    # deterministic routes (weight R(1 − a) there) agree with the stochastic branch (photons, every
    # reflection drawn); with R alone they read 3.27 against 2.23 ± 0.10 mm².
    s = dict(clear_semi_diameter=32.0, mechanical_semi_diameter=32.0)
    surfaces = (Surface(thickness=5.0, material="N-BK7", coating="uncoated", **s),
                Surface(thickness=95.0, coating="uncoated", **s),
                Surface(radius=-200.0, thickness=-70.0, mirror=True, is_stop=True, clear_semi_diameter=30.0,
                        mechanical_semi_diameter=30.0, coating="R=0.9"),
                Surface(radius=-600.0 / 7.0, thickness=100.0, mirror=True, clear_semi_diameter=10.0,
                        mechanical_semi_diameter=10.0, coating="R=0.9"))
    p = Prescription(surfaces, Aperture("epd", 60.0))
    zs = p.vertex_z
    v1, t1 = _cap(Profile.of(surfaces[2]), zs[2], 30.0, 16, 64)
    v2, t2 = _cap(Profile.of(surfaces[3]), zs[3], 10.0, 6, 48)
    mirrors = TaggedMesh(np.vstack([v1, v2]), np.vstack([t1[64:], t2 + len(v1)]),
                         np.concatenate([np.zeros(len(t1) - 64, np.int32), np.ones(len(t2), np.int32)]),
                         [FaceTag("mirror-1", "mirror", "optical", "polished", surface=2, face=0),
                          FaceTag("mirror-2", "mirror", "optical", "polished", surface=3, face=0)])
    mesh = TaggedMesh.concatenate([primitives.lens_element(p, 0, 1, 32.0, part="window", rings=8, segments=64),
                                   mirrors, primitives.disk((0.0, 0.0, zs[3] - 1.0), 10.5, part="spider")])
    scene = make_scene(p, mesh, detector={"width_mm": 12.0, "height_mm": 12.0, "pixels": [8, 8], "z_mm": 130.0},
                       source={"type": "collimated", "off_axis_deg": 0.5, "azimuth_deg": 90.0},
                       finishes={"roughness": _abg(0.3, 0.01)}, assign={"*": "absorber", "surface:3": "roughness"},
                       effects={"scatter": True, "ghosts": True, "direct": False, "absorption": False})
    tracer = Tracer(scene)
    branch, branch_se = ghosts_channel(scene, tracer, EstimatorSettings(ghost_routes=False), 100_000, 6)
    routes, routes_se = ghosts_channel(scene, tracer, EstimatorSettings(), 20_000, 3)
    assert routes == pytest.approx(branch, abs=4 * math.hypot(branch_se, routes_se))
    assert 4 * math.hypot(branch_se, routes_se) < 0.2 * branch  # 1/(1 − a) = 1.43 would fail it


CASSEGRAIN_ZMX = Path(__file__).resolve().parents[1] / "optics" / "corpus" / "HoO-V2C18Ex03.zmx"


def _init(design: Path) -> None:
    from typer.testing import CliRunner

    from lensmount.cli import app

    result = CliRunner().invoke(app, ["init", str(design), "--lens", str(CASSEGRAIN_ZMX)])
    assert result.exit_code == 0, result.output


def test_init_gives_a_mirror_lens_finishes_whose_mirrors_scatter_as_polished_mirrors(tmp_path):
    from lensmount.design.finishes import load_finishes
    from lensmount.design.scene import load_scene
    from lensmount.physics.bsdf import make_bsdf

    _init(tmp_path / "design")
    finishes = load_finishes(tmp_path / "design")
    assert finishes.assign == {"*": "lambert-5", "surface:2": "polished-mirror", "surface:3": "polished-mirror"}
    spec = load_scene(tmp_path / "design" / "scenes" / "case2-lambertian.toml", finishes)
    assert spec.assign == finishes.assign  # every scene of the design has them
    params = dict(spec.finishes["polished-mirror"])
    tis = make_bsdf(params.pop("model"), **params).tis
    assert tis == pytest.approx((4 * math.pi * 0.002 / 0.55) ** 2, rel=0.01)  # 2 nm rms at 550 nm


@pytest.mark.slow  # ~30 s: the regenerate
def test_the_corpus_cassegrain_simulates_its_mirrors_scatter(tmp_path):
    import json

    from typer.testing import CliRunner

    from lensmount.cli import app

    design = tmp_path / "design"
    _init(design)
    runner = CliRunner()
    assert runner.invoke(app, ["regenerate", str(design), "--quiet"]).exit_code == 0
    out = tmp_path / "run"
    run = runner.invoke(app, ["simulate", str(design), "--scene", str(design / "scenes" / "case2-lambertian.toml"),
                              "--photons-per-pass", "20000", "--passes", "3", "--workers", "1",
                              "--method", "forward", "--out", str(out), "--no-record"])
    assert run.exit_code == 0, run.output
    summary = json.loads((out / "summary.json").read_text())
    ran = [d["what"] for d in summary["plan"]["ran"]]
    assert "scatter at mirror surface 2 (mirror-2)" in ran and "scatter at mirror surface 3 (mirror-1)" in ran
    assert math.isfinite(summary["stray_fraction"]) and summary["stray_fraction"] > 0.0
    paths = [[(e.get("part"), e.get("role")) for e in p["events"]] for p in summary["top_paths"]["paths"]]
    names = [e["name"] for p in summary["top_paths"]["paths"] for e in p["events"]]
    assert "mirror-2 face 0 (mirror surface 2)" in names
    # the sun on the primary, scattered by it to the detector: 3.3e-6 of 1.9e-5, third after the secondary's
    # cell and its bevel (Lambertian 5 %) at 3 x 20k photons
    assert [("mirror-2", "optical")] in paths


def test_the_view_map_of_a_cassegrain_aims_at_the_secondary_it_sees_through_the_primarys_hole():
    from lensmount.integrators.photon_mapping.view_map import exit_disc

    scene = _cassegrain(None)
    disc = exit_disc(scene, scene.detector)
    # the secondary (10 mm, vertex at z = −70, its rim behind it), not the primary (30 mm, z = 0) nearer
    assert (disc.facing, disc.z, disc.radius) == (-1.0, pytest.approx(-70.0), pytest.approx(10.0 * 1.05 + 0.5))


@pytest.mark.slow  # ~25 s
def test_bidirectional_sees_the_baffle_the_secondary_shows_the_detector():
    # the baffle tube's front end (z = −40), lit by the image beam, is seen by the detector only in the
    # secondary: backward rays aimed at the primary (30 mm) read 0.0001 ± 0.0001 against the forward
    # 0.086 ± 0.004 (4 × 100k, 16 samples per pixel); aimed at the secondary 0.077 ± 0.010
    scene = _cassegrain(None, 1.0, baffle=0.5, direct=False, tube_from=-40.0)
    tracer = Tracer(scene)
    runs = []
    for run in (lambda i: forward_pass(scene, tracer, 100_000, 1, i),
                lambda i: bidirectional_pass(scene, tracer, 100_000, 1, i, 1.0, samples_per_pixel=16)):
        flux = np.array([run(i).flux for i in range(4)])
        runs.append((flux.mean(), flux.std(ddof=1) / 2.0))
    (mf, sf), (mb, sb) = runs
    assert mf > 10.0 * sf and abs(mf - mb) <= 3.0 * math.hypot(sf, sb), runs
