"""The ghosts channel of forward passes: (mean, standard error) over independent passes, shared by
the tests that compare the deterministic ghost routes with the stochastic reflection branch."""

import math

import numpy as np

from lensmount.integrators.estimate import film_channels
from lensmount.integrators.forward import Forward


def ghosts_channel(scene, tracer, settings, photons: int, passes: int, seed: int = 11):
    ghosts = film_channels(scene).index("ghosts")
    flux = np.array([Forward(settings).run_pass(scene, tracer, i, photons, seed).part_flux[ghosts]
                     for i in range(passes)])
    return flux.mean(), flux.std(ddof=1) / math.sqrt(passes)
