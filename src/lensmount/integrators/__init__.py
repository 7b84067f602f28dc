"""The integrators: estimators of the detector's irradiance, pass by pass.

    registry.py        the `Integrator` protocol and `INTEGRATORS` (what `simulate --method` names)
    forward.py         plug-in: forward light tracing, the unbiased reference
    bidirectional.py   plug-in: bidirectional stochastic ray tracing; its own machinery is photon_mapping/
    walk.py            the photon walk both share (with scatter_aim.py, exit_sampler.py, ghost_routes.py,
                       lobe_core.py: which part of a glossy lobe the photons count)
    estimate.py        the film, the energy ledger and a pass's estimate (paths.py: path signatures)
    settings.py        the run's knobs (`EstimatorSettings`); plan.py the effects planner
"""
