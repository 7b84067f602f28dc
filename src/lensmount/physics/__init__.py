"""lensmount.physics — what a scene is made of, independent of how it is traced.

    physics.sources     SunSource, CollimatedSource, ObjectSource, emission_disc, source_direction
    physics.detector    Detector: pixels and deposits
    physics.interfaces  Snell, total internal reflection, Fresnel, coatings (Coating, parse_coating)
    physics.bsdf        one BSDF per module, registered in `BSDFS`, made by `make_bsdf` (docs/bsdf.md)
    physics.rays        RayBatch: structure-of-arrays rays with masks
    physics.sampler     Streams, stream: the only source of randomness

Imports nothing of lensmount but `errors`: the engine (`lensmount.trace`) and the integrators
consume these; the scene (`lensmount.scene`) assembles them.
"""
