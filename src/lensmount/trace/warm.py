"""Compile the tracer's numba kernels into their cache once: `python -m lensmount.trace.warm`
(`make install` runs it).

Why: numba compiles a kernel on its first call and keeps the machine code beside the source
(`cache=True`). Cold, the tracer's kernels take ~10-20 s to compile on the 2-core machine; the
first `simulate` would pay that, and so would each of its worker processes that starts before
the cache is written. Tracing rays through an uncoated window inside a tube, with the Fresnel
branch off and on, in a batch large enough for the walk on every core and in a small one, calls
every kernel with the argument types of a real run (a new combination of types would compile
again).
"""

from __future__ import annotations

import time

import numpy as np

from lensmount.design.scene import scene_from_dict
from lensmount.mesh import TaggedMesh
from lensmount.optics.prescription import Aperture, Prescription, Surface
from lensmount.physics.rays import RayBatch
from lensmount.physics.sampler import Streams
from lensmount.scene import primitives
from lensmount.scene.build import build_scene
from lensmount.trace import kernels, lens_kernel
from lensmount.trace.tracer import Tracer


def main() -> None:
    start = time.perf_counter()
    sd = dict(clear_semi_diameter=20.0, mechanical_semi_diameter=20.0)
    lens = Prescription((Surface(thickness=5.0, material="SCHOTT:N-BK7", **sd), Surface(thickness=50.0, **sd)),
                        Aperture("epd", 40.0))
    mesh = TaggedMesh.concatenate([primitives.lens_elements(lens, [20.0, 20.0], rings=4, segments=24),
                                   primitives.tube(-10.0, 60.0, 21.0, 25.0)])
    n = lens_kernel.THREADED_FROM  # as many as a real batch: the walk on every core compiles too
    rng = np.random.default_rng(0)
    r = 30.0 * np.sqrt(rng.random(n))  # inside the glass, on the tube, and past it
    phi = 2.0 * np.pi * rng.random(n)
    origin = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.full(n, -20.0)])
    tilt = np.radians(20.0) * rng.random(n)
    direction = np.column_stack([np.sin(tilt), np.zeros(n), np.cos(tilt)])
    for ghosts in (False, True):
        spec = scene_from_dict({
            "description": "numba cache warm-up",
            "source": {"type": "sun", "off_axis_deg": 0.0, "azimuth_deg": 90.0},
            "detector": {"width_mm": 40.0, "height_mm": 40.0, "pixels": [4, 4]},
            "effects": {"scatter": True, "ghosts": ghosts, "direct": True},
            "coatings": {"default": "uncoated"},
            "assign": {"*": "absorber"},
        })
        tracer = Tracer(build_scene(lens, mesh, spec))
        rays = RayBatch.make(origin, direction, wavelength=np.zeros(n, np.int64))
        events = tracer.next_event(rays, Streams(0, "warm", np.arange(n)))
        tracer.next_event(RayBatch.make(events.position, -events.direction, wavelength=np.zeros(n, np.int64)),
                          Streams(0, "warm", np.arange(n)), origin_normal=events.normal)
        tracer.intersect(rays)
        few = rays.subset(slice(0, 64))  # fewer than THREADED_FROM: the walk on one core
        tracer.next_event(few, Streams(0, "warm", np.arange(64)))
    # Only rays past a silhouette edge ask for the boxes near a point; the rays above may meet none.
    kernels.boxes_near(np.zeros((1, 3)), np.zeros((1, 2, 3)), 0.0, *kernels.box_grid(np.zeros((1, 2, 3))))
    # Only a hit near a face it shares no vertex with asks for its neighbours; the rays above may meet none.
    kernels.neighbours_near(np.zeros((1, 3)), np.zeros(1, np.int64), np.zeros(2, np.int64), np.zeros(0, np.int64),
                            np.zeros((1, 2, 3)), np.zeros((1, 3)), np.zeros((1, 3)), 0.0)
    print(f"lensmount: tracer kernels compiled and cached ({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
