"""The tagged mesh: every triangle keeps a tag back to its part, role and CAD face.

This is the one geometry object the tracer reads. Saved as `mesh.npz`
(vertices, triangles, tags, and the tag table as JSON) so it loads in
milliseconds and other tools can open it with numpy alone.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
import numpy as np

from lensmount.atomic import NPZ_DAMAGE, write_npz
from lensmount.errors import InputError

ROLES = ("optical", "lens-edge", "bevel", "mount", "diaphragm-edge", "vane-edge", "object")
KINDS = ("lens", "barrel", "spacer", "retainer", "diaphragm", "vane", "hood", "housing", "baffle", "object")


@dataclass(frozen=True)
class FaceTag:
    """What a triangle belongs to.

    Args:
        part: part name, unique in the assembly (`lens-1`, `spacer-2`, `diaphragm`).
        kind: part kind, one of KINDS.
        role: face role, one of ROLES; `optical` faces are refined analytically.
        finish: finish name from mount.toml (a scene may override it).
        surface: 0-based prescription surface index for optical faces, else -1.
        face: CAD face index within the part (a STEP part's: the face's index in the file's solid).
        label: the face's name in a user's STEP file ("" for generated faces).
        assigned: how the mount file gave this face its own finish (a STEP part's `names`, `colours`,
            `layers` or `rules`: "colour #1a1a1a"); "" when the face has its part's finish. A face's
            own finish is more specific than any finishes.toml rule but `finish:NAME`.
    """

    part: str
    kind: str
    role: str
    finish: str
    surface: int = -1
    face: int = 0
    label: str = ""
    assigned: str = ""


@dataclass
class TaggedMesh:
    """Triangles with a tag each.

    vertices : (V, 3) float64, mm, assembly frame (optical axis +z, surface 1 vertex at z = 0)
    triangles : (T, 3) int64 vertex indices, counter-clockwise seen from outside the solid
    tags : (T,) int32 index into `tag_table`
    """

    vertices: np.ndarray
    triangles: np.ndarray
    tags: np.ndarray
    tag_table: list[FaceTag] = field(default_factory=list)

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, dtype=np.float64).reshape(-1, 3)
        self.triangles = np.ascontiguousarray(self.triangles, dtype=np.int64).reshape(-1, 3)
        self.tags = np.ascontiguousarray(self.tags, dtype=np.int32).reshape(-1)
        if len(self.tags) != len(self.triangles):
            raise ValueError("one tag per triangle")

    @property
    def parts(self) -> list[str]:
        """Part names in first-seen order."""
        return list(dict.fromkeys(t.part for t in self.tag_table))

    def part_of_tag(self) -> np.ndarray:
        """(n_tags,) index into `parts` for every tag."""
        names = {p: i for i, p in enumerate(self.parts)}
        return np.array([names[t.part] for t in self.tag_table], dtype=np.int32)

    def part_extents(self) -> dict[str, dict]:
        """What each part is and where: its kind, its axial extent `z_mm` [min, max] and radial extent `r_mm`
        [min, max] (mm, over its triangles' vertices); what `compare` matches parts across revisions by."""
        kinds = {t.part: t.kind for t in self.tag_table}
        names = self.parts
        if not len(self.triangles) or not names:
            return {}
        part = np.repeat(self.part_of_tag()[self.tags], 3)  # one entry per triangle corner
        corner = self.vertices[self.triangles.reshape(-1)]
        r = np.hypot(corner[:, 0], corner[:, 1])
        extent = {}
        for label, values in (("z_mm", corner[:, 2]), ("r_mm", r)):
            low, high = np.full(len(names), np.inf), np.full(len(names), -np.inf)
            np.minimum.at(low, part, values)
            np.maximum.at(high, part, values)
            extent[label] = (low, high)
        return {name: {"kind": kinds[name],
                       **{label: [round(float(lo[i]), 4), round(float(hi[i]), 4)] for label, (lo, hi) in extent.items()}}
                for i, name in enumerate(names) if np.isfinite(extent["z_mm"][0][i])}

    def select(self, mask: np.ndarray) -> "TaggedMesh":
        """The triangles where mask is true (vertices kept; fine for tracing)."""
        return TaggedMesh(self.vertices, self.triangles[mask], self.tags[mask], list(self.tag_table))

    @staticmethod
    def concatenate(meshes: list["TaggedMesh"]) -> "TaggedMesh":
        verts, tris, tags, table = [], [], [], []
        v0 = 0
        for m in meshes:
            verts.append(m.vertices)
            tris.append(m.triangles + v0)
            tags.append(m.tags + len(table))
            table.extend(m.tag_table)
            v0 += len(m.vertices)
        if not meshes:
            return TaggedMesh(np.zeros((0, 3)), np.zeros((0, 3), int), np.zeros(0, np.int32), [])
        return TaggedMesh(np.concatenate(verts), np.concatenate(tris), np.concatenate(tags), table)

    def save(self, path: str | os.PathLike) -> None:
        """Write atomically (temp file + rename)."""
        write_npz(path, compressed=True, vertices=self.vertices, triangles=self.triangles, tags=self.tags,
                  tag_table=np.array(json.dumps([asdict(t) for t in self.tag_table])))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "TaggedMesh":
        """The mesh; InputError naming the file when it is damaged (regenerate checks its own
        outputs' checksums first and rebuilds a damaged one, so this is a file given by hand)."""
        try:
            with np.load(path, allow_pickle=False) as z:
                table = [FaceTag(**t) for t in json.loads(str(z["tag_table"]))]
                return cls(z["vertices"], z["triangles"], z["tags"], table)
        except NPZ_DAMAGE as e:
            raise InputError(f"the mesh is damaged and cannot be read ({type(e).__name__}: {e})", file=str(path),
                             valid="a mesh.npz as `lensmount regenerate` writes it: regenerate the design "
                                   "(it rebuilds a damaged build folder)") from None
