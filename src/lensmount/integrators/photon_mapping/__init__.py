"""The bidirectional integrator's own machinery (`integrators/bidirectional.py` runs it pass by pass).

    view_map.py       phase 1: backward samples from every pixel → hit points (radius r, weight τ, ω_o)
    targets.py        where backward samples are aimed: the exit pupil's discs, a learned edge band
    media.py          the detector's medium: radiance seen in glass or oil is n² that in air
    radius.py         r₀ per hit point, s_i per pass, the on-face gather area (numba kernels)
    neighbours.py     the k nearest hit points on a face (numba kernel)
    photon_target.py  photons started where a pilot found they meet a thin edge
    photon_gather.py  phase 2: photons deposited into the hit points within r (numba kernels)
    connect.py        faces the detector sees straight: each photon there joined to a detector point

Nothing here imports a plug-in; the walk, the film and the ledger it uses are the shared ones below it
(`.importlinter`, "Inside integrators").
"""
