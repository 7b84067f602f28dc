"""Tracer throughput on the reference lens and mount.

Prints:
- rays/s of a full non-sequential trace (`Tracer.next_event`: every refraction of the double
  Gauss, analytic refinement, to the detector) of an f/7 bundle at 0° and 3.5°, as a lone
  process runs it (the compiled walk on every core) and on one core (as each `simulate` worker
  runs it);
- the raw embreex intersection rate (one nearest-hit query per ray) on the same mesh and the
  same number of rays, and the ratio of the two;
- Embree queries per traced ray (probes + relaunches past facets);
- one pass's view map of case 2 on one core: its CPU per backward segment against the forward
  trace's per segment on one core (issue 28 asks <= 2x), and the backward rays' own share;
- optiland's non-sequential tracer through the same lens, in the same run (rays/s and ratio,
  against both of ours: optiland's numpy runs on one core);
- the same bundle traced by an independent optics package (rayoptics, sequential, one ray at
  a time in Python) as a peer, with the largest landing-point difference.

Mesh: `lensmount.cad.regenerate` of examples/double-gauss-360.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from importlib.metadata import version

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
N_RAYS = 200_000
N_PEER = 1_000
N_OPTILAND = 50_000


def _reference():
    from lensmount.cad.pipeline import regenerate
    from lensmount.mesh import TaggedMesh
    from lensmount.design.lens import load_lens
    from lensmount.design.finishes import load_finishes
    from lensmount.design.scene import load_scene
    from lensmount.scene.build import build_scene

    design = ROOT / "examples" / "double-gauss-360"
    p = load_lens(design / "lens.toml")
    out = Path(tempfile.gettempdir()) / "lensmount-bench-trace"  # regenerate's cache makes reruns fast
    manifest = regenerate(design, out)
    mesh = TaggedMesh.load(out / manifest.mesh)
    spec = load_scene(design / "scenes" / "case2-lambertian.toml", load_finishes(design))
    return p, mesh, build_scene(p, mesh, spec)


def _bundle(p, n, rng, field_deg=3.5, fill=0.45):
    """n rays, half on axis and half at field_deg, uniform over a disc of fill × EPD radius in the entrance pupil."""
    from lensmount.optics.paraxial import paraxial

    par = paraxial(p)
    field = np.where(rng.random(n) < 0.5, 0.0, np.radians(field_deg))
    d = np.column_stack([np.zeros(n), np.sin(field), np.cos(field)])
    r = fill * par.epd * np.sqrt(rng.random(n))
    ph = 2 * np.pi * rng.random(n)
    pupil = np.column_stack([r * np.cos(ph), r * np.sin(ph), np.full(n, par.entrance_pupil_z)])
    origin = pupil - ((par.entrance_pupil_z + 150.0) / d[:, 2])[:, None] * d
    return origin, d


def _rayoptics_peer(p, origins, dirs):
    """Trace with rayoptics; returns (rays/s, landing points (n, 3) in our frame) or a reason."""
    try:
        from rayoptics.environment import OpticalModel, PupilSpec, FieldSpec, WvlSpec
        from rayoptics.raytr import trace as rtrace
    except Exception as exc:
        return f"rayoptics not installed ({exc.__class__.__name__}); `pip install -e '.[bench]'`", None
    from lensmount.optics.glass import refractive_index

    wl_um = p.primary_wavelength_um
    opm = OpticalModel()
    sm, osp = opm["seq_model"], opm["optical_spec"]
    osp["pupil"] = PupilSpec(osp, key=["object", "epd"], value=51.43)
    osp["fov"] = FieldSpec(osp, key=["object", "angle"], flds=[0.0])
    osp["wvls"] = WvlSpec([(wl_um * 1000.0, 1.0)], ref_wl=0)
    opm.radius_mode = True
    object_gap = 1000.0  # a finite object gap keeps the launch points exact in float64
    sm.gaps[0].thi = object_gap
    for s in p.surfaces:
        # The same indices as ours at this wavelength (a peer for the geometry, not the catalogue).
        n = float(refractive_index(s.material, wl_um))
        sm.add_surface([s.radius if np.isfinite(s.radius) else 0.0, s.thickness, n, 64.0])
        if s.is_stop:
            sm.set_stop()
    opm.update_model()
    # rayoptics launches in the object surface's frame, `object_gap` in front of surface 1.
    wvl = wl_um * 1000.0
    t0 = time.perf_counter()
    pts = np.full((len(origins), 3), np.nan)
    for i, (o, d) in enumerate(zip(origins, dirs)):
        try:
            ray = rtrace.trace(sm, o + [0.0, 0.0, object_gap], d.copy(), wvl)[0]
        except Exception:  # rayoptics signals a miss by raising; count it as not arrived
            continue
        pts[i] = ray[-1][0]
    dt = time.perf_counter() - t0
    pts[:, 2] = p.image_z
    return len(origins) / dt, pts


def _optiland_peer(p, n):
    """optiland's non-sequential tracer through the same lens (same radii, thicknesses and
    glasses, the stop in air folded into its gap: the converter has no bare stop): rays/s or a
    reason."""
    try:
        import warnings

        from optiland.nonsequential.convert import sequential_to_nonsequential
        from optiland.optic import Optic
    except Exception as exc:
        return f"optiland not installed ({exc.__class__.__name__}); `pip install -e '.[bench]'`"
    op = Optic()
    op.add_surface(index=0, radius=np.inf, thickness=np.inf)
    rows = []
    for s in p.surfaces:
        glass = s.material.upper() != "AIR"
        if s.is_stop and not glass and not np.isfinite(s.radius) and rows and not rows[-1][2]:
            rows[-1][1] += s.thickness
            continue
        rows.append([s.radius, s.thickness, s.material.split(":")[-1] if glass else None])
    for k, (r, t, m) in enumerate(rows, start=1):
        op.add_surface(index=k, radius=r if np.isfinite(r) else np.inf, thickness=t, **({"material": m} if m else {}))
    op.add_surface(index=len(rows) + 1)
    op.set_aperture(aperture_type="EPD", value=0.9 * 51.43)
    op.set_field_type(field_type="angle")
    op.add_field(y=0.0)
    op.add_field(y=3.5)
    op.add_wavelength(value=p.primary_wavelength_um, is_primary=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = sequential_to_nonsequential(op, detector_width=40.0)
        scene.trace(2000, seed=1)  # warm-up
        t0, c0 = time.perf_counter(), time.process_time()
        res = scene.trace(n, seed=1)
        dt, dc = time.perf_counter() - t0, time.process_time() - c0
    return n / dt, float(res.total_flux_detected), n / dc


def _view_map_line(scene, tracer, forward_cpu_per_segment: float) -> None:
    """One pass's view map of case 2 (600 × 600 px, a backward sample each, every mount face Lambertian) on
    one core, as `Bidirectional.run_pass` builds it: its CPU per backward segment against the forward
    trace's per segment (the bench bundle, one core), the tracing alone and with the hit points' radii and
    on-face areas."""
    from lensmount.integrators.bidirectional import _scene_tables, gather_cores
    from lensmount.integrators.estimate import scattering_tags
    from lensmount.integrators.settings import EstimatorSettings
    from lensmount.integrators.photon_mapping.view_map import build_view_map, view_map_streams
    from lensmount.scene.scene import optical_faces

    cfg = EstimatorSettings()
    half_widths, boundaries = _scene_tables(scene, cfg.radius_cap_mm, cfg.normal_limit_deg)
    core = gather_cores(scene.bsdf_of_tag, cfg.glossy_threshold_deg, cfg.gathered_share)
    core[~scattering_tags(scene)] = np.inf
    core[optical_faces(scene.mesh.tag_table)] = np.inf
    det = scene.detector

    def view_map(pass_index):
        return build_view_map(scene, tracer, det, view_map_streams(1, pass_index, det, 1), broad=np.isfinite(core),
                              half_widths=half_widths, radius_scale=1.0, boundaries=boundaries, pilot_seed=1)

    view_map(0)  # compiles, and the learned edge target's pilot when the scene has one
    traced = [0.0]
    trace = tracer.next_event

    def timed(*args, **kwargs):  # the backward rays' own share: the tracer's calls, timed
        c = time.process_time()
        out = trace(*args, **kwargs)
        traced[0] += time.process_time() - c
        return out

    tracer.next_event = timed
    tracer.segments = 0
    c0 = time.process_time()
    hits = view_map(1)
    whole, segments = time.process_time() - c0, tracer.segments
    del tracer.next_event
    samples = det.nx * det.ny
    per = whole / segments
    print(f"view map of case 2 on one core ({samples} backward samples, {segments / samples:.1f} segments each, "
          f"{len(hits.weight)} hit points): {whole:.2f} s CPU, {per * 1e9:.0f} ns per backward segment = "
          f"{per / forward_cpu_per_segment:.1f}x the forward trace's {forward_cpu_per_segment * 1e9:.0f} ns per "
          f"segment (one core, CPU; target 2x); the backward rays alone (Tracer.next_event) {traced[0]:.2f} s, "
          f"{traced[0] / segments / forward_cpu_per_segment:.1f}x per segment")


def main() -> None:
    from lensmount.physics.rays import RayBatch
    from lensmount.trace.tracer import DETECTOR, Tracer

    t0 = time.perf_counter()
    p, mesh, scene = _reference()
    print(f"mesh: {len(mesh.triangles)} triangles from cad.regenerate ({time.perf_counter() - t0:.1f} s)")
    import numba

    from lensmount.trace import lens_kernel

    t0 = time.perf_counter()
    tracer = Tracer(scene)
    print(f"Tracer build (Embree BVH): {time.perf_counter() - t0:.3f} s")
    rng = np.random.default_rng(1)
    o, d = _bundle(p, N_RAYS, rng)
    rays = RayBatch.make(o, d, wavelength=np.full(N_RAYS, p.primary_wavelength))
    tracer.next_event(rays.subset(slice(0, 2000)))  # warm-up
    tracer.embree_rays = 0
    tracer.segments = 0
    t0, c0 = time.perf_counter(), time.process_time()
    ev = tracer.next_event(rays)
    full, full_cpu = time.perf_counter() - t0, time.process_time() - c0
    arrived = (ev.kind == DETECTOR).mean()
    print(f"full non-sequential trace on {numba.get_num_threads()} threads ({numba.threading_layer()}): "
          f"{N_RAYS / full:,.0f} rays/s ({N_RAYS} rays, {full:.2f} s, "
          f"{arrived:.1%} reach the detector, {tracer.embree_rays / N_RAYS:.1f} Embree queries per ray: "
          f"{tracer.mechanical.queries / N_RAYS:.1f} against the metal, {tracer._optical_queries / N_RAYS:.1f} for glass "
          f"facets; the compiled walk proves the other steps without Embree)")

    # Raw embreex: one nearest-hit query per ray against the whole mesh (all triangles, one scene).
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    whole = rtcs.EmbreeScene()
    TriangleMesh(whole, (mesh.vertices - tracer.centre).astype(np.float32), mesh.triangles.astype(np.int32))
    start = (o - tracer.centre).astype(np.float32)
    dirs = d.astype(np.float32)
    whole.run(start[:2000], dirs[:2000], query="INTERSECT", output=1)
    t0, c0 = time.perf_counter(), time.process_time()
    whole.run(start, dirs, query="INTERSECT", output=1)
    raw, raw_cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"raw embreex nearest-hit: {N_RAYS / raw:,.0f} rays/s (same mesh, same {N_RAYS} rays)")
    per_query = tracer.embree_rays / N_RAYS
    made = (f"per Embree query made: {full / per_query / raw:.1f}x the raw cost in wall time, "
            f"{full_cpu / per_query / raw_cpu:.1f}x in CPU time" if tracer.embree_rays
            else "no Embree query was needed: every step was proven analytically")
    print(f"ratio raw embreex / full trace: {full / raw:.1f}x ({made}; CPU time is what other processes on the "
          f"machine move less)")
    # A tracer that asks Embree for every straight piece of a path needs one nearest-hit query per
    # segment; the compiled walk proves most of them without Embree, so this is the cost to compare.
    per_segment = tracer.segments / N_RAYS
    print(f"per traced segment ({per_segment:.1f} per ray: refractions + 1): {full / per_segment / raw:.2f}x the raw "
          f"cost of one nearest-hit query in wall time, {full_cpu / per_segment / raw_cpu:.2f}x in CPU time")

    # Rays that meet the mount take the exact Embree path: its own cost per query, on a bundle that
    # overfills the pupil at 7° (light on the diaphragm, the barrel and the lens edges).
    o_s, d_s = _bundle(p, N_RAYS, np.random.default_rng(2), field_deg=7.0, fill=0.7)
    stray = RayBatch.make(o_s, d_s, wavelength=np.full(N_RAYS, p.primary_wavelength))
    tracer.embree_rays = 0
    tracer.segments = 0
    t0, c0 = time.perf_counter(), time.process_time()
    tracer.next_event(stray)
    s_wall, s_cpu = time.perf_counter() - t0, time.process_time() - c0
    q, seg = tracer.embree_rays / N_RAYS, tracer.segments / N_RAYS
    print(f"stray bundle (7°, 1.4x the pupil, to the first mechanical face or the detector): {N_RAYS / s_wall:,.0f} "
          f"rays/s, {seg:.1f} segments and {q:.1f} Embree queries per ray; per segment {s_wall / seg / raw:.2f}x the "
          f"raw cost of one query in wall time, {s_cpu / seg / raw_cpu:.2f}x in CPU time; "
          + (f"per Embree query {s_cpu / q / raw_cpu:.1f}x in CPU time, the walk's steps included" if q
             else "no Embree query was needed"))

    # One core, as each worker process of `simulate` traces (its neighbours have the other cores).
    lens_kernel.one_core_per_process()
    tracer.next_event(rays.subset(slice(0, 2000)))
    tracer.segments = 0
    t0, c0 = time.perf_counter(), time.process_time()
    tracer.next_event(rays)
    one_core, one_core_cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"full non-sequential trace on one core: {N_RAYS / one_core:,.0f} rays/s "
          f"(on every core it took {full / one_core:.2f}x this time)")
    _view_map_line(scene, tracer, one_core_cpu / tracer.segments)

    peer = _optiland_peer(p, N_OPTILAND)
    if isinstance(peer, str):
        print(f"peer optiland: {peer}")
    else:
        print(f"peer optiland {version('optiland')} non-sequential (same lens, same run, one core): {peer[0]:,.0f} "
              f"rays/s ({N_OPTILAND} rays, {peer[1]:.0%} of the flux detected); lensmount full trace is "
              f"{(N_RAYS / full) / peer[0]:.1f}x faster in wall time on every core, "
              f"{(N_RAYS / one_core) / peer[0]:.1f}x on one core, {(N_RAYS / full_cpu) / peer[2]:.1f}x in CPU time")

    sel = slice(0, N_PEER)
    rate, pts = _rayoptics_peer(p, o[sel], d[sel])
    if pts is None:
        print(f"peer: {rate}")
    else:
        ok = (ev.kind[sel] == DETECTOR) & np.isfinite(pts[:, 0])
        diff = np.abs(pts[ok, :2] - ev.position[sel][ok, :2]).max()
        print(f"peer rayoptics 0.9 (sequential, per-ray Python): {rate:,.0f} rays/s; "
              f"lensmount full trace is {(N_RAYS / full) / rate:.0f}x faster; "
              f"largest landing difference {diff:.2e} mm over {ok.sum()} rays")


if __name__ == "__main__":
    main()
