"""Adapter between the tracer's events and the bidirectional integrator.

The integrator needs, per ray and per call, only: did it end on a mechanical face
(where, which tag, which normal), on the detector (where), or nowhere; its travel
direction and weight after the optics. This module turns `Tracer.next_event` output
into that `Step`, so a change in the tracer's event record touches one file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lensmount.trace.rays import RayBatch

GONE, FACE, DETECTOR = 0, 1, 2


@dataclass
class Step:
    """Where each of N rays ended this call.

    kind : (N,) int8, GONE (escaped, absorbed by glass, killed), FACE or DETECTOR
    position : (N, 3) mm
    direction : (N, 3) unit travel direction arriving at the event
    normal : (N, 3) unit face normal on the side the ray came from (FACE only)
    tag : (N,) int32 face tag (FACE only, else -1)
    weight : (N,) throughput after the optics (Fresnel branch choice, absorption)
    wavelength, id : (N,) carried through
    lost : (N,) bool, ended by a numerical guard of the tracer (weight = lost flux)
    reflections : (N,) Fresnel (ghost) reflections during this step, or None
    prim : (N,) triangle index for FACE (else -1), or None when the tracer has no mesh
    """

    kind: np.ndarray
    position: np.ndarray
    direction: np.ndarray
    normal: np.ndarray
    tag: np.ndarray
    weight: np.ndarray
    wavelength: np.ndarray
    id: np.ndarray
    lost: np.ndarray | None = None
    reflections: np.ndarray | None = None
    prim: np.ndarray | None = None


def next_step(tracer, rays: RayBatch, rng: np.random.Generator, origin_normal: np.ndarray | None = None) -> Step:
    """Advance every live ray to its next mechanical face, the detector, or out.

    origin_normal (N, 3): normal of the face each ray leaves (rays scattered at a face);
    the tracer needs it to keep rays leaving near a concave corner from slipping through.
    """
    if hasattr(tracer, "next_step"):  # tracers that already speak `Step` (the test scenes' planar tracer)
        return tracer.next_step(rays, rng)
    ev = tracer.next_event(rays, rng, origin_normal=origin_normal)
    return from_events(ev, rays)


def from_events(ev, rays: RayBatch) -> Step:
    """`trace.tracer.Events` → Step (the tracer uses the same kind codes)."""
    return Step(kind=np.asarray(ev.kind, np.int8), position=ev.position, direction=ev.direction, normal=ev.normal,
                tag=np.asarray(ev.tag, np.int32), weight=ev.weight, wavelength=np.asarray(ev.wavelength, np.int32),
                id=ev.id, lost=ev.lost, reflections=ev.reflections, prim=ev.prim)
