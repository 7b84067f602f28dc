"""lensmount.cad: layout, checks, STEP export, tagged tessellation and the regenerate cache.

`regenerate(design_dir, out_dir, progress=None) -> Manifest` is the entry point;
importing this package stays light (the CAD kernel loads on first use).
"""


def regenerate(design_dir, out_dir=None, progress=None, use_cache: bool = True, tessellation=None):
    """See lensmount.cad.pipeline.regenerate."""
    from lensmount.cad.pipeline import regenerate as _regenerate

    return _regenerate(design_dir, out_dir, progress=progress, use_cache=use_cache, tessellation=tessellation)


__all__ = ["regenerate"]
