"""lensmount.trace — the engine: the non-sequential ray tracer that consumes a Scene.

    from lensmount.design.finishes import load_finishes
    from lensmount.design.lens import load_lens
    from lensmount.design.scene import load_scene
    from lensmount.mesh import TaggedMesh
    from lensmount.scene.build import build_scene
    from lensmount.trace.tracer import Tracer
    from lensmount.physics.rays import RayBatch
    from lensmount.physics.sampler import stream
    from lensmount.integrators.forward import forward_pass

    lens = load_lens("examples/double-gauss-360/lens.toml")
    mesh = TaggedMesh.load("out/double-gauss-360/mesh.npz")          # from `lensmount regenerate`
    spec = load_scene("examples/double-gauss-360/scenes/case2-lambertian.toml",
                      load_finishes("examples/double-gauss-360"))                 # the design's finishes
    scene = build_scene(lens, mesh, spec)
    tracer = Tracer(scene)

    # Trace your own rays to the next mechanical face / the detector:
    rays = RayBatch.make(origins, directions, wavelength=wavelength_index)   # (N, 3), (N, 3), (N,)
    events = tracer.next_event(rays, stream(1, "my-rays"))
    events.kind, events.position, events.tag, events.pixel, events.weight

    # Photons from the scene's sun, one pass of the forward estimator:
    est = forward_pass(scene, tracer, n_photons=1_000_000, seed=1, pass_index=0)

Modules: `tracer` (Tracer, Hits, Events: intersection and glass interfaces), `kernels` and
`lens_kernel` (the compiled steps and walk), `mechanical` (Embree on the metal), `ghosts`
(sequential ghost routes), `warm` (compiles the kernels once). What a scene is made of
(sources, detector, coatings, BSDFs, rays, the sampler) is `lensmount.physics`.
Full description: docs/tracer.md.
"""
