"""lensmount.trace — the non-sequential ray tracer, as a scriptable API.

    from lensmount.design.lens import load_lens
    from lensmount.design.scene import load_scene
    from lensmount.cad.mesh import TaggedMesh
    from lensmount.scene import build_scene
    from lensmount.trace import Tracer, RayBatch, stream
    from lensmount.integrators.forward import forward_pass

    lens = load_lens("examples/double-gauss-360/lens.toml")
    mesh = TaggedMesh.load("out/double-gauss-360/mesh.npz")          # from `lensmount regenerate`
    scene = build_scene(lens, mesh, load_scene("examples/double-gauss-360/scenes/case2-lambertian.toml"))
    tracer = Tracer(scene)

    # Trace your own rays to the next mechanical face / the detector:
    rays = RayBatch.make(origins, directions, wavelength=wavelength_index)   # (N, 3), (N, 3), (N,)
    events = tracer.next_event(rays, stream(1, "my-rays"))
    events.kind, events.position, events.tag, events.pixel, events.weight

    # Photons from the scene's sun, one pass of the forward estimator:
    est = forward_pass(scene, tracer, n_photons=1_000_000, seed=1, pass_index=0)
    est.image            # (ny, nx) irradiance / E_sun
    est.part_flux        # (P,) mm² per part, names in est.part_names

Contents:
    Tracer, Hits, Events, GONE, FACE, DETECTOR     (trace.tracer)   intersection + glass interfaces
    SunSource, CollimatedSource, EmissionDisc,
    emission_disc, source_direction                (trace.sources)  sources at infinity
    Detector                                       (trace.detector) pixels, deposits
    Coating, parse_coating, refract, reflect,
    fresnel_rt, reflectance                        (trace.interfaces) Snell, TIR, Fresnel, coatings
    RayBatch                                       (trace.rays)     structure-of-arrays rays
    stream, Streams                                (trace.sampler)  the only source of randomness
BSDF models: `lensmount.bsdf` (trace/bsdf/). Full description: docs/tracer.md.
"""

from lensmount.trace.detector import Detector
from lensmount.trace.interfaces import Coating, fresnel_rt, parse_coating, reflect, reflectance, refract
from lensmount.trace.rays import RayBatch
from lensmount.trace.sampler import Streams, stream
from lensmount.trace.sources import CollimatedSource, EmissionDisc, SunSource, emission_disc, source_direction
from lensmount.trace.tracer import DETECTOR, FACE, GONE, Events, Hits, Tracer

__all__ = ["Tracer", "Hits", "Events", "GONE", "FACE", "DETECTOR", "SunSource", "CollimatedSource",
           "EmissionDisc", "emission_disc", "source_direction", "Detector", "Coating", "parse_coating",
           "refract", "reflect", "fresnel_rt", "reflectance", "RayBatch", "stream", "Streams"]
