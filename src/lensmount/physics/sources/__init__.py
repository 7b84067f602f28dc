"""Light sources, one module per kind, each registering itself in `SOURCES`:

    base.py         the `Source` protocol, the direction convention, where a scene places a source
                    (`Placement`), the [source] table's parameters and the registry
    at_infinity.py  the sun (a 0.53° disc) and a collimated point source
    object.py       an object at a finite distance: a point or a Lambertian disc
"""

from lensmount.physics.sources.at_infinity import CollimatedParams, CollimatedSource, SunParams, SunSource
from lensmount.physics.sources.base import (
    SOURCES, EmissionDisc, Placement, Source, SourceParams, disc_radius_fraction, emission_disc, entering_fraction,
    no_light_enters_reason, orthonormal_basis, source_direction, source_params)
from lensmount.physics.sources.object import DiscParams, ObjectSource, PointParams

__all__ = ["Source", "Placement", "SourceParams", "SunParams", "CollimatedParams", "PointParams",
           "DiscParams", "SOURCES", "source_params", "SunSource", "CollimatedSource", "ObjectSource",
           "EmissionDisc", "emission_disc", "source_direction",
           "orthonormal_basis", "entering_fraction", "no_light_enters_reason", "disc_radius_fraction"]
