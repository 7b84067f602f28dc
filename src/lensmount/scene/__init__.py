"""lensmount.scene — the Scene (pure data) and how it is built from lens + mesh + scene spec.

    scene.scene       Scene, OpticalSurface, Effects, FrontOpening
    scene.build       build_scene(prescription, mesh, spec) -> Scene, make_source
    scene.primitives  disk, rectangle, box, sphere, tube, lens_element (test and object meshes)

Finishes and their rules are part of the design (`lensmount.design.finishes`).
"""
