"""Where the stray light comes from: paths down to the CAD face, and critical ∩ illuminated faces.

`PathSums` is the run's sum of the passes' `PassPaths` and `PassFaces` (part of the
`Accumulator`, so of the checkpoint): per path signature Σ flux and Σ flux² over the passes
(its standard error is the spread of the passes, as the channels'), a binned image for the
`KEPT_IMAGES` paths carrying most flux so far, and per face Σ lit flux, Σ étendue seen and
a binned image of the detector's view of it.

A path's image is the mean over the passes since it entered the kept set (each pass is an
unbiased estimate, so a path kept late has a noisier image, never a wrong one).

Reports (`top_paths`, `face_report`) name every event in the CAD's words: part, CAD face,
role, finish. Critical ∩ illuminated (the faces a stray-light engineer fixes first): a face's
*critical* measure is the étendue G (mm²·sr) with which the detector sees it, from the view
map's backward samples; its *illuminated* measure the irradiance E = Φ/A the photons bring;
their product G·E/π is the flux a white Lambertian finish there would send to the detector,
so the ranking is the finish-independent potential of each face.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from lensmount.analysis.error_bar import MIN_PASSES, t_factor
from lensmount.analysis.metrics import finite_or_none, stray_fraction
from lensmount.atomic import write_npz
from lensmount.integrators.paths import EMPTY, PassFaces, ghost_of, PassPaths, binned_pixel, binned_shape
from lensmount.mesh import FaceTag

KEPT_IMAGES = 48  # paths whose images the run keeps (the most flux so far)
FACE_LIST = 10  # faces per list in the report


def _t_error(total: np.ndarray, total_sq: np.ndarray, n: int) -> np.ndarray:
    """Standard error of the mean from Σx and Σx² over n passes × Student-t (inf below 3 passes)."""
    if n < MIN_PASSES:
        return np.full(len(total), math.inf)
    mean = total / n
    var = np.maximum(total_sq / n - mean * mean, 0.0) * n / (n - 1)
    return np.sqrt(var / n) * t_factor(n)


@dataclass
class PathSums:
    """Sums over passes of per-path and per-face light (see the module docstring)."""

    n: int = 0
    shape: tuple[int, int] = (0, 0)
    block: int = 1
    signature: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    total: np.ndarray = field(default_factory=lambda: np.zeros(0))
    total_sq: np.ndarray = field(default_factory=lambda: np.zeros(0))
    events: dict[int, tuple[int, ...]] = field(default_factory=lambda: {EMPTY: ()})
    image_signature: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    images: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))
    image_passes: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    face_passes: int = 0
    lit: np.ndarray = field(default_factory=lambda: np.zeros(0))
    seen_passes: int = 0
    seen: np.ndarray = field(default_factory=lambda: np.zeros(0))
    seen_images: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 0)))

    @property
    def binned(self) -> tuple[int, int]:
        return binned_shape(self.shape, self.block)

    def add(self, paths: PassPaths, faces: PassFaces) -> None:
        if self.n == 0:
            self.shape, self.block = tuple(paths.shape), int(paths.block)
            self.images = np.zeros((0, *self.binned))
        elif (tuple(paths.shape), paths.block) != (self.shape, self.block):
            raise ValueError("pass path images differ in shape from the run's")
        if not (np.isfinite(paths.flux).all() and np.isfinite(paths.image_value).all()):
            raise ValueError("pass path flux is not finite")
        self.n += 1
        union = np.union1d(self.signature, paths.signature)
        total, total_sq = np.zeros(len(union)), np.zeros(len(union))
        old = np.searchsorted(union, self.signature)
        total[old], total_sq[old] = self.total, self.total_sq
        new = np.searchsorted(union, paths.signature)
        total[new] += paths.flux
        total_sq[new] += paths.flux * paths.flux
        self.signature, self.total, self.total_sq = union, total, total_sq
        self.events.update(paths.events)
        self._add_images(paths)
        self._add_faces(faces)

    def _add_images(self, paths: PassPaths) -> None:
        stray = self.signature != EMPTY
        order = np.argsort(-self.total[stray], kind="stable")[:KEPT_IMAGES]
        top = self.signature[stray][order]
        images = np.zeros((len(top), *self.binned))
        passes = np.ones(len(top), np.int64)
        where = {int(s): i for i, s in enumerate(self.image_signature.tolist())}
        lo = np.searchsorted(paths.image_signature, top, side="left")
        hi = np.searchsorted(paths.image_signature, top, side="right")
        for k, s in enumerate(top.tolist()):
            if s in where:
                images[k] = self.images[where[s]]
                passes[k] += self.image_passes[where[s]]
            if hi[k] > lo[k]:
                images[k].reshape(-1)[:] += np.bincount(paths.image_pixel[lo[k]:hi[k]],
                                                        weights=paths.image_value[lo[k]:hi[k]],
                                                        minlength=images[k].size)
        self.image_signature, self.images, self.image_passes = top.astype(np.int64), images, passes

    def _add_faces(self, faces: PassFaces) -> None:
        n_tags = len(faces.lit)
        if self.face_passes == 0:
            self.lit, self.seen = np.zeros(n_tags), np.zeros(n_tags)
            self.seen_images = np.zeros((n_tags, *self.binned))
        self.face_passes += 1
        self.lit += faces.lit
        if faces.seen is not None:
            self.seen_passes += 1
            self.seen += faces.seen
            n_binned = int(np.prod(self.binned))
            self.seen_images.reshape(-1)[:] += np.bincount(faces.seen_tag * n_binned + faces.seen_pixel,
                                                           weights=faces.seen_value, minlength=self.seen_images.size)

    # -- the answer ------------------------------------------------------------------------

    def mean_flux(self) -> np.ndarray:
        return self.total / max(self.n, 1)

    def std_error(self) -> np.ndarray:
        return _t_error(self.total, self.total_sq, self.n)

    def pixels_per_block(self) -> np.ndarray:
        """(cny, cnx) detector pixels in each block (edge blocks may hold fewer)."""
        ny, nx = self.shape
        counts = np.bincount(binned_pixel(np.arange(ny * nx), self.shape, self.block), minlength=int(np.prod(self.binned)))
        return counts.reshape(self.binned).astype(np.float64)

    def path_image(self, signature: int) -> np.ndarray | None:
        """Mean irradiance image (cny, cnx) E/E_sun of one path, None when its image was not kept."""
        hit = np.flatnonzero(self.image_signature == signature)
        if not len(hit):
            return None
        k = int(hit[0])
        return self.images[k] / self.image_passes[k] / self.pixels_per_block()

    # -- checkpoint ------------------------------------------------------------------------

    def arrays(self) -> dict[str, np.ndarray]:
        sigs = sorted(self.events)
        codes = [self.events[s] for s in sigs]
        return dict(
            paths_n=np.int64(self.n), paths_shape=np.array(self.shape, np.int64), paths_block=np.int64(self.block),
            paths_signature=self.signature, paths_total=self.total, paths_total_sq=self.total_sq,
            paths_event_signature=np.array(sigs, np.int64), paths_event_length=np.array([len(c) for c in codes], np.int64),
            paths_event_codes=np.array([c for cs in codes for c in cs], np.int64),
            paths_image_signature=self.image_signature, paths_images=self.images, paths_image_passes=self.image_passes,
            faces_passes=np.int64(self.face_passes), faces_lit=self.lit, faces_seen_passes=np.int64(self.seen_passes),
            faces_seen=self.seen, faces_seen_images=self.seen_images)

    @classmethod
    def from_arrays(cls, z) -> "PathSums":
        ends = np.cumsum(z["paths_event_length"])
        codes = z["paths_event_codes"].tolist()
        events = {int(s): tuple(codes[e - n:e]) for s, n, e in
                  zip(z["paths_event_signature"].tolist(), z["paths_event_length"].tolist(), ends.tolist())}
        return cls(n=int(z["paths_n"]), shape=tuple(int(v) for v in z["paths_shape"]), block=int(z["paths_block"]),
                   signature=z["paths_signature"].copy(), total=z["paths_total"].copy(),
                   total_sq=z["paths_total_sq"].copy(), events=events,
                   image_signature=z["paths_image_signature"].copy(), images=z["paths_images"].copy(),
                   image_passes=z["paths_image_passes"].copy(), face_passes=int(z["faces_passes"]),
                   lit=z["faces_lit"].copy(), seen_passes=int(z["faces_seen_passes"]), seen=z["faces_seen"].copy(),
                   seen_images=z["faces_seen_images"].copy())


# -- reports ------------------------------------------------------------------------------------

def face_name(tag) -> str:
    """A CAD face in the user's words: part and face index, and the face's name in a user's STEP file."""
    return f"{tag.part} face {int(tag.face)}" + (f" '{tag.label}'" if tag.label else "")


def describe_event(code: int, tag_table) -> dict:
    """One event in the CAD's words."""
    if code < 0:
        n, first, second = ghost_of(code)
        pair = [s + 1 for s in (first, second) if s >= 0]  # 1-based, as Zemax and the ghost report
        return {"ghost_reflections": n, "ghost_pair": pair, "role": "ghost",
                "name": f"ghost {'–'.join(f'S{s}' for s in pair)}" + (f" ({n} reflections)" if n != 2 else "")}
    t = tag_table[code]
    out = {"part": t.part, "face": int(t.face), "role": t.role, "kind": t.kind, "finish": t.finish, "tag": int(code),
           "label": t.label, "name": f"{face_name(t)} ({t.role})"}
    if t.role == "optical":  # a mirror's coated face, scattering: named by its surface as the lens file numbers it
        out |= {"surface": int(t.surface) + 1, "name": f"{face_name(t)} (mirror surface {t.surface + 1})"}
    return out


def signature_from_hex(text: str) -> int:
    """The int64 signature of its 16-digit hex form in `top_paths` (unsigned)."""
    return int(np.array([int(text, 16)], np.uint64).view(np.int64)[0])


def ghost_pairs(sums: PathSums, aperture_flux_mm2: float) -> list[dict]:
    """The ghosts channel by surface pair, strongest first: every path of a single ghost stretch (light
    that reached the detector unscattered after Fresnel reflections), named by the surfaces of its first
    two reflections (1-based, in the order the light meets them) and its reflection count, with its
    stray fraction, standard error (the passes' spread: photons, or the deterministic routes'
    randomised lattices; null below 3 passes) and share of the channel. Empty with ghosts off."""
    scale = 1.0 / aperture_flux_mm2 if aperture_flux_mm2 > 0 else 0.0
    flux, se = sums.mean_flux(), sums.std_error()
    rows = []
    for k, s in enumerate(sums.signature.tolist()):
        codes = sums.events.get(int(s), ())
        if len(codes) == 1 and codes[0] < 0:
            n, first, second = ghost_of(codes[0])
            rows.append(([x + 1 for x in (first, second) if x >= 0], n, float(flux[k]), float(se[k])))
    total = sum(f for _, _, f, _ in rows)
    table = [{"surfaces": pair, "reflections": n, "fraction": finite_or_none(f * scale),
              "std_error": finite_or_none(e * scale) if math.isfinite(e) else None,
              "share": finite_or_none(f / total) if total > 0 else 0.0} for pair, n, f, e in rows]
    return sorted(table, key=lambda r: r["fraction"] or 0.0, reverse=True)


def top_paths(sums: PathSums, tag_table, aperture_flux_mm2: float, top: int = 10) -> dict:
    """The `top` stray paths by mean flux, each with its ordered events, fraction of the aperture
    flux (the unit of `stray_fraction`) and standard error; `other` sums the rest, so the listed
    fractions plus `other` add up to the stray fraction of every path (`direct` left out)."""
    flux, se = sums.mean_flux(), sums.std_error()
    stray = np.flatnonzero(sums.signature != EMPTY)
    order = stray[np.argsort(-flux[stray], kind="stable")]
    total = float(flux[stray].sum())
    scale = 1.0 / aperture_flux_mm2 if aperture_flux_mm2 > 0 else 0.0
    rows = []
    for rank, k in enumerate(order[:top], 1):
        sig = int(sums.signature[k])
        rows.append({"rank": rank, "signature": f"{sig & (2**64 - 1):016x}",
                     "events": [describe_event(c, tag_table) for c in sums.events[sig]],
                     "fraction": finite_or_none(stray_fraction(float(flux[k]), aperture_flux_mm2)),
                     "std_error": finite_or_none(float(se[k]) * scale) if math.isfinite(se[k]) else None,
                     "share": finite_or_none(float(flux[k]) / total) if total > 0 else None,
                     "flux_mm2": finite_or_none(float(flux[k])),
                     "image_kept": bool(np.any(sums.image_signature == sig))})
    rest = order[top:]
    other = float(flux[rest].sum())
    other_se = math.sqrt(float(np.sum(se[rest] ** 2))) if len(rest) else 0.0
    return {"paths": rows, "distinct_paths": int(len(stray)),
            "other": {"paths": int(len(rest)), "fraction": finite_or_none(stray_fraction(other, aperture_flux_mm2)),
                      "std_error": finite_or_none(other_se * scale) if math.isfinite(other_se) else None},
            "total_fraction": finite_or_none(stray_fraction(total, aperture_flux_mm2)), "passes": int(sums.n)}


def scene_tags(scene) -> list:
    """The mesh's tag table with the finish each face has in this scene (its `[assign]` rules)."""
    finishes = scene.finish_of_tag or [t.finish for t in scene.mesh.tag_table]
    return [replace(t, finish=f) for t, f in zip(scene.mesh.tag_table, finishes)]


def face_areas(mesh) -> np.ndarray:
    """(n_tags,) area of every CAD face (mm²), from its triangles."""
    v, tri = mesh.vertices, mesh.triangles
    a = 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]]), axis=1)
    return np.bincount(mesh.tags, weights=a, minlength=len(mesh.tag_table))[: len(mesh.tag_table)]


def face_measures(sums: PathSums, areas: np.ndarray) -> dict[str, np.ndarray]:
    """Per face: lit flux Φ (mm²), irradiance E = Φ/A (E/E_sun), étendue G (mm²·sr, nan-free: 0
    without a view map) and the product G·E/π (mm²): all means per pass."""
    lit = sums.lit / max(sums.face_passes, 1)
    irradiance = np.where(areas > 0, lit / np.where(areas > 0, areas, 1.0), 0.0)
    seen = sums.seen / max(sums.seen_passes, 1) if sums.seen_passes else np.zeros_like(lit)
    return {"lit": lit, "irradiance": irradiance, "seen": seen, "product": seen * irradiance / math.pi}


def face_report(sums: PathSums, tag_table, areas: np.ndarray, aperture_flux_mm2: float, top: int = FACE_LIST) -> dict:
    """Faces both critical (seen by the detector) and illuminated (lit by the source), ranked by G·E/π;
    then the critical-but-unlit (by G) and lit-but-not-critical (by E). Empty lists without a view map
    (forward runs, or a plan with nothing to gather): `view_map` false."""
    m = face_measures(sums, areas)
    critical, lit = m["seen"] > 0, m["lit"] > 0
    if not sums.seen_passes:  # what the detector sees is unknown, not nothing: no list claims it
        critical = lit = np.zeros_like(lit)

    def row(t: int) -> dict:
        tag = tag_table[t]
        return {"part": tag.part, "face": int(tag.face), "label": tag.label, "name": face_name(tag), "role": tag.role,
                "kind": tag.kind, "finish": tag.finish, "tag": int(t), "area_mm2": finite_or_none(areas[t]),
                "irradiance": finite_or_none(m["irradiance"][t]), "lit_flux_mm2": finite_or_none(m["lit"][t]),
                "etendue_mm2_sr": finite_or_none(m["seen"][t]), "product_mm2": finite_or_none(m["product"][t]),
                "product_fraction": finite_or_none(stray_fraction(float(m["product"][t]), aperture_flux_mm2))}

    def ranked(mask: np.ndarray, by: np.ndarray) -> list[dict]:
        idx = np.flatnonzero(mask)
        return [row(int(t)) for t in idx[np.argsort(-by[idx], kind="stable")][:top]]

    return {"critical_and_illuminated": ranked(critical & lit, m["product"]),
            "critical_unlit": ranked(critical & ~lit, m["seen"]),
            "lit_not_critical": ranked(lit & ~critical, m["irradiance"]),
            "view_map": bool(sums.seen_passes),
            "units": {"etendue": "mm²·sr", "irradiance": "E/E_sun",
                      "product": "mm² (flux / E_sun) a white Lambertian finish would send: G·E/π"}}


def write_paths(path: str | os.PathLike, sums: PathSums, tag_table, areas: np.ndarray, aperture_flux_mm2: float,
                extent_mm: tuple[float, float, float, float]) -> None:
    """paths.npz beside summary.json: what `lensmount paths` needs (the sums, the tag table, face areas)."""
    write_npz(path, compressed=True, **sums.arrays(), aperture_flux_mm2=np.float64(aperture_flux_mm2),
              extent_mm=np.array(extent_mm, np.float64), face_areas=np.asarray(areas, np.float64),
              tag_table=np.array(json.dumps([asdict(t) for t in tag_table])))


def read_paths(path: str | os.PathLike):
    """(PathSums, tag_table, face areas, aperture flux, extent) from a paths.npz."""
    with np.load(path, allow_pickle=False) as z:
        sums = PathSums.from_arrays(z)
        table = [FaceTag(**t) for t in json.loads(str(z["tag_table"]))]
        return sums, table, z["face_areas"].copy(), float(z["aperture_flux_mm2"]), tuple(float(v) for v in z["extent_mm"])


__all__ = ["PathSums", "scene_tags", "face_name", "signature_from_hex", "KEPT_IMAGES", "top_paths", "ghost_pairs", "face_report", "face_measures", "face_areas", "describe_event",
           "write_paths", "read_paths"]
