"""Light sources, for scripts: `from lensmount.sources import SunSource`.

    SunSource(direction, angular_diameter_deg=0.53, limb_darkening=False)
    CollimatedSource(direction)               # point source at infinity, for PST sweeps
    ObjectSource(centre, radius, ...)         # a point or Lambertian disc at a finite distance
    source_direction(off_axis_deg, azimuth_deg) -> unit (3,) vector of travel

Photons start on a disc normal to the source direction that covers the
assembly's front opening; each carries flux A_disc / N in units of E_sun·mm², so
results do not depend on the disc's size. Implementation: lensmount.trace.sources.
"""

from lensmount.trace.sources import (CollimatedSource, EmissionDisc, ObjectSource, SunSource, emission_disc,
                                     source_direction)

__all__ = ["SunSource", "CollimatedSource", "ObjectSource", "EmissionDisc", "emission_disc", "source_direction"]
