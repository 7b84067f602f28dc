"""The loop an engineer runs many times a day, as Python functions: regenerate → simulate → compare.

Each takes a typed options record and returns a typed result; the CLI modules only
parse options, call these and print. Scripts and notebooks call them directly:

    from lensmount.loop.simulate import SimulateOptions, simulate
    result = simulate(SimulateOptions(Path("mylens"), Path("mylens/scenes/case1.toml"), passes=8))
    result.summary["stray_fraction"], result.paths["exr"]

Modules: `regenerate`, `simulate`, `compare`, `history`, `sweep`, `optimize`, `pst`, `converge`,
`sightlines` (`check`), `ghosts` (ghost ranking), and their helpers `prepare`, `progress`,
`provenance`.
"""
