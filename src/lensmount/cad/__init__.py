"""lensmount.cad: layout, checks, STEP export, tagged tessellation and the regenerate cache.

`lensmount.cad.pipeline.regenerate(design_dir, out_dir, progress=None) -> Manifest` is the entry
point; `cad.starter` plans the first mount of a lens (`lensmount init`). The CAD kernel
(build123d/OCP) loads on first use inside the modules that need it, for start-up time.
"""
