"""`regenerate`: design folder → STEP, tagged mesh, manifest (lensmount.cad, content-addressed cache).

`simulate` calls this with the same default folder as `lensmount regenerate`
(DESIGN/build), so a simulation after a regenerate reuses that geometry instead of
building its own copy.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:  # the CAD pipeline loads matplotlib: lensmount --help must not
    from lensmount.cad.pipeline import Manifest


@dataclass(frozen=True)
class RegenerateOptions:
    """design : design folder; out : output folder (default DESIGN/build);
    use_cache : False rebuilds even when the inputs are unchanged;
    tessellation : overrides of mount.toml's [tessellation]."""

    design: Path
    out: Path | None = None
    use_cache: bool = True
    tessellation: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RegenerateResult:
    folder: Path
    manifest: Manifest

    @property
    def triangles(self) -> int:
        return sum(p.triangles for p in self.manifest.parts)


def regenerate(options: RegenerateOptions, progress: Callable[[str, int, int], None] | None = None
               ) -> RegenerateResult:
    """Build (or restore from the cache) the mount's CAD outputs; progress(step, done, total)."""
    # lazy: keeps lensmount --help from loading cad and matplotlib
    from lensmount.cad.pipeline import regenerate as build

    folder = Path(options.out) if options.out is not None else Path(options.design) / "build"
    manifest = build(options.design, folder, progress=progress, use_cache=options.use_cache,
                     tessellation=dict(options.tessellation) or None)
    return RegenerateResult(folder, manifest)


def warm(design: Path) -> None:
    """Keep the design's CAD warm in this process, writing nothing (`cad.pipeline.warm`): a long-lived
    caller then regenerates an edit at the cost of the parts it changed."""
    # lazy: keeps lensmount --help from loading cad and matplotlib
    from lensmount.cad.pipeline import warm as warm_parts

    warm_parts(design)


__all__ = ["RegenerateOptions", "RegenerateResult", "regenerate", "warm"]
