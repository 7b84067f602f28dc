"""lensmount.scene — the Scene (pure data) and how it is built from lens + mesh + scene file.

    Scene, OpticalSurface, Effects, FrontOpening      (scene.scene)
    build_scene(prescription, mesh, spec) -> Scene    (scene.build)
    BUILTIN_FINISHES, finish_of                       (scene.finishes)
    disk, rectangle, box, sphere, tube, lens_element  (scene.primitives)
"""

from lensmount.scene.build import build_scene
from lensmount.scene.finishes import BUILTIN_FINISHES, finish_of
from lensmount.scene.scene import Effects, FrontOpening, OpticalSurface, Scene

__all__ = ["Scene", "OpticalSurface", "Effects", "FrontOpening", "build_scene", "BUILTIN_FINISHES", "finish_of"]
