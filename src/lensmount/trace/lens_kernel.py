"""The walk of rays through the lens as one compiled loop (numba): no Embree, no numpy per step.

Why: after the sequential step and the conic roots were compiled (CHANGELOG.md, "The walk through the lens"), the
time of `Tracer.next_event` went to the live-set bookkeeping around each step — ~15 arrays
fancy-indexed per refraction — and to Snell + Fresnel in numpy. Here a ray stays in one loop
iteration from glass surface to glass surface until something needs Embree.

A step is taken only when it is proven, else the ray is handed back unchanged:

- the next glass crossing is the sequential step's (`kernels.step_one`: exact inside the
  facets' safe radius, no other surface's slab entered);
- no mechanical face lies on the segment: the *clear bore* (`clear_bore`) is, per z bin, the
  smallest distance from the axis of any mechanical triangle reaching into that bin; the
  distance from the axis is convex along a straight segment, so a segment whose two ends are
  both nearer the axis than the bore of every bin it crosses meets no metal (a float64
  inequality with a margin: no Embree query, no float32);
- the detector rectangle is the analytic one of `Detector.intersect`;
- a mirror surface is left to `Tracer` (its reflection and any scatter there are decided in
  one place).

The refraction, total internal reflection, coating reflectance (coatings as per-surface
tables: kind code and constant R) and the Fresnel branch are the formulas of
`physics.interfaces` and `Tracer._interface`, written per ray in the same order. The branch's
uniform is `sampler.Streams.at`'s splitmix64 hash of the ray's key and dimension
FRESNEL_DIM + its interface count, so it is the same number either path draws.
"""

from __future__ import annotations

import cmath
import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from lensmount.physics.interfaces import MGF2_DESIGN_WAVELENGTH_UM, MGF2_INDEX
from lensmount.trace.jit_cache import drop_damaged
from lensmount.trace.kernels import step_one

# step_one (with `kernels.face_table`'s column numbers) is compiled into this file's cached walk, and numba
# keys that cache on this file's text alone: an edit of kernels.py leaves the walk stale until this file
# changes or its cache (__pycache__/lens_kernel.*) is removed (tests/trace failed on one: it and
# `kernels.sequential_step` disagree). `make install` removes the trace kernels' cache whenever either
# file changes, before it compiles them again.

class LensTables(NamedTuple):
    """The lens as the walk reads it, per optical surface (built once by `Tracer`; numba takes a
    named tuple of arrays as one argument)."""

    faces: np.ndarray  # kernels.face_table: the sequential step's per-surface table
    curvature: np.ndarray
    conic: np.ndarray
    t_min: float  # mm, the smallest step (scene scale)
    n_before: np.ndarray  # (S, W) index on the -z side
    n_after: np.ndarray  # (S, W) index on the +z side
    alpha_before: np.ndarray  # (S, W) bulk absorption, 1/mm
    alpha_after: np.ndarray
    absorbs: bool
    coating_code: np.ndarray  # COATING_CODES
    coating_r: np.ndarray  # a constant coating's R
    wavelengths: np.ndarray  # µm
    mirror: np.ndarray  # bool: left to the Tracer


class DetectorPlane(NamedTuple):
    z: float
    half_width: float
    half_height: float


COATING_CODES = {"perfect-ar": 0, "uncoated": 1, "mgf2-quarter-wave": 2, "constant": 3}
# Constants copied from interfaces and sampler on purpose: numba freezes globals into its on-disk cache,
# which it invalidates only when this file changes, so an imported value edited there would leave a
# stale kernel. tests/trace/test_lens_kernel.py holds the copies to their originals.
_MGF2_THICKNESS_UM = MGF2_DESIGN_WAVELENGTH_UM / (4.0 * MGF2_INDEX)  # a quarter wave; numba reads it as a constant
_COS_FLOOR = 1e-12
_DETECTOR = 2  # tracer.DETECTOR (tracer imports this module)
THREADED_FROM = 4096  # rays: below, starting the threads costs more than they save

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


# ---------------------------------------------------------------------------------- clear bore

@njit(cache=True)
def _bin_minimum(z_lo, z_hi, r_min, z0, inv_h, nb):
    """Per z bin: the smallest r_min of the triangles whose z range reaches into it."""
    bore = np.full(nb, np.inf)
    for j in range(z_lo.shape[0]):
        b0 = max(int(math.floor((z_lo[j] - z0) * inv_h)), 0)
        b1 = min(int(math.floor((z_hi[j] - z0) * inv_h)), nb - 1)
        for b in range(b0, b1 + 1):
            if r_min[j] < bore[b]:
                bore[b] = r_min[j]
    return bore


def axis_distance(a, b, c) -> np.ndarray:
    """(m,) the smallest distance from the z axis of triangles with corners a, b, c (m, 3): the
    distance from the origin to the triangle's projection on the xy plane (0 if it covers the axis)."""
    p = [v[:, :2] for v in (a, b, c)]
    edge_distance = []
    for u, v in ((p[0], p[1]), (p[1], p[2]), (p[2], p[0])):
        e = v - u
        s = np.clip(-np.einsum("ij,ij->i", u, e) / np.maximum(np.einsum("ij,ij->i", e, e), 1e-300), 0.0, 1.0)
        edge_distance.append(np.hypot(*(u + s[:, None] * e).T))
    cross = [u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0] for u, v in ((p[0], p[1]), (p[1], p[2]), (p[2], p[0]))]
    covers = (np.minimum.reduce(cross) >= 0.0) | (np.maximum.reduce(cross) <= 0.0)
    return np.where(covers, 0.0, np.minimum.reduce(edge_distance))


def clear_bore(a, b, c, bins: int = 4096):
    """The clear bore of triangles with corners a, b, c (m, 3): (z0, 1/bin width, sparse table
    (levels, bins) of range minima of `axis_distance`, margin)."""
    r_min = axis_distance(a, b, c)
    z = np.column_stack([a[:, 2], b[:, 2], c[:, 2]])
    z_lo, z_hi = z.min(axis=1), z.max(axis=1)
    if len(z_lo) == 0:
        return 0.0, 1.0, np.full((1, 1), np.inf), 0.0
    z0, z1 = float(z_lo.min()), float(z_hi.max())
    extent = max(z1 - z0, float(np.abs(np.concatenate([a, b, c])).max()), 1e-6)
    inv_h = bins / max(z1 - z0, 1e-6)
    table = [_bin_minimum(z_lo, z_hi, r_min, z0, inv_h, bins)]
    while 2 ** len(table) <= bins:
        prev, half = table[-1], 2 ** (len(table) - 1)
        table.append(np.concatenate([np.minimum(prev[:-half], prev[half:]), np.full(half, np.inf)]))
    # Rounding of the radii above and of the segment ends is ~1e-16 of the assembly size.
    return z0, inv_h, np.array(table), 1e-9 * extent


@njit(cache=True, inline="always")
def _clear_piece(ax, ay, az, bx, by, bz, z0, inv_h, table, margin):
    nb = table.shape[1]
    b0 = max(int(math.floor((min(az, bz) - z0) * inv_h)), 0)
    b1 = min(int(math.floor((max(az, bz) - z0) * inv_h)), nb - 1)
    if b1 < b0:
        return True  # wholly in front of or behind every mechanical face
    level = 0
    while (2 << level) <= b1 - b0 + 1:
        level += 1
    bore = min(table[level, b0], table[level, b1 - (1 << level) + 1])
    return math.sqrt(max(ax * ax + ay * ay, bx * bx + by * by)) < bore - margin


@njit(cache=True, inline="always")
def _clear(ox, oy, oz, dx, dy, dz, t_end, z0, inv_h, table, margin):
    """No mechanical face on the segment o + [0, t_end] d (see `clear_bore`): whole, else each
    half that is not, down to 32nds (a beam narrowing through a diaphragm between two lens
    groups is far inside the bore everywhere, but its ends are not inside the diaphragm's).
    Depth first, in order: piece `index` of 2**level spans t_end·[index, index + 1] / 2**level
    (powers of two: neighbouring pieces share their end points exactly)."""
    level, index = 0, 0
    while True:
        n = 1 << level
        ta, tb = t_end * index / n, t_end * (index + 1) / n
        if _clear_piece(ox + ta * dx, oy + ta * dy, oz + ta * dz, ox + tb * dx, oy + tb * dy, oz + tb * dz,
                        z0, inv_h, table, margin):
            while index & 1:  # the right half done: up to the parent's
                level -= 1
                index >>= 1
            if level == 0:
                return True
            index += 1
        elif level == 5:
            return False
        else:
            level += 1
            index <<= 1


# ---------------------------------------------------------------------------------- interface

@njit(cache=True, inline="always")
def uniform(key, dim):
    """`Streams.at` for one ray: splitmix64 of (key, dim), as a float64 in [0, 1)."""
    z = key ^ (np.uint64(dim) + _GOLDEN)
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@njit(cache=True)
def _complex_cos(n0, sin0, n):
    s = (n0 * sin0) / n
    c = cmath.sqrt(complex(1.0 - s * s))
    return -c if c.imag < 0 else c


@njit(cache=True)
def _admittances(n, cos):
    if abs(cos) < _COS_FLOOR:
        cos = complex(_COS_FLOOR)
    return n * cos, n / cos


@njit(cache=True)
def _layer_r(m11, m12, m21, m22, e0, e2):
    b = m11 + m12 * e2
    c = m21 + m22 * e2
    den = e0 * b + c
    if abs(den) < 1e-300:
        den = complex(1e-300)
    return min(max(abs((e0 * b - c) / den) ** 2, 0.0), 1.0)


# Inlined (like `_clear`): the walk calls both on every step, most often to learn "0" (perfect AR) or "clear".
@njit(cache=True, inline="always")
def reflectance(n1, n2, cos_i, code, r_const, wavelength_um):
    """`interfaces.reflectance` for one ray: unpolarised R of coating `code` (COATING_CODES)."""
    cos_i = min(max(cos_i, 0.0), 1.0)
    sin_i = math.sqrt(max(0.0, 1.0 - cos_i * cos_i))
    if n1 * sin_i > n2:
        return 1.0
    if code == 0:
        return 0.0
    if code == 3:
        return r_const
    cos0 = complex(cos_i)
    cos2 = _complex_cos(n1, sin_i, n2)
    e0s, e0p = _admittances(n1, cos0)
    e2s, e2p = _admittances(n2, cos2)
    if code == 1:
        one, zero = complex(1.0), complex(0.0)
        rs = _layer_r(one, zero, zero, one, e0s, e2s)
        rp = _layer_r(one, zero, zero, one, e0p, e2p)
    else:
        cosf = _complex_cos(n1, sin_i, MGF2_INDEX)
        delta = 2.0 * np.pi * MGF2_INDEX * _MGF2_THICKNESS_UM * cosf / wavelength_um
        efs, efp = _admittances(MGF2_INDEX, cosf)
        cd, sd = cmath.cos(delta), cmath.sin(delta)
        rs = _layer_r(cd, 1j * sd / efs, 1j * efs * sd, cd, e0s, e2s)
        rp = _layer_r(cd, 1j * sd / efp, 1j * efp * sd, cd, e0p, e2p)
    return 0.5 * (rs + rp)


# ---------------------------------------------------------------------------------- the walk

@njit(cache=True)
def _walk_rays(j0, j1, over, work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal, reflections, ghost_pair,
               lost, keys, ghosts, lens, bore, detector, fresnel_dim, max_optical):
    """Rays work[j0:j1] of `walk`; over[j]: True when ray j's call is over. Reads and writes only rows work[j] of
    the arrays, so rays can walk on any core in any order with the same result. A run of rays per call, not one:
    each call takes and drops a reference to every array it unpacks (an atomic count each, ~60 a call), which
    per ray cost more than a tenth of the walk."""
    faces, curv, conic, t_min, nbef, naft, abef, aaft, absorbs, code, r_const, wavelengths, mirror = lens
    z0, inv_h, table, margin = bore
    det_z, det_hw, det_hh = detector
    for j in range(j0, j1):  # over[j] stays False unless the ray's call is over
        i = work[j]
        while count[i] < max_optical:
            ox, oy, oz, dx, dy, dz = o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1], d[i, 2]
            sure, t, s = step_one(left_s[i], ox, oy, oz, dx, dy, dz, np.inf, faces, t_min)
            if not sure:
                break
            t_det = np.inf
            if abs(dz) > 1e-300:
                td = (det_z - oz) / dz
                tf = td if math.isfinite(td) else 0.0
                if abs(ox + tf * dx) <= det_hw and abs(oy + tf * dy) <= det_hh and td > t_min:
                    t_det = td
            on_det = t_det < t
            t_end = t_det if on_det else t
            if not math.isfinite(t_end):
                # No glass and no detector ahead: the ray leaves if nothing mechanical is on its way
                # out of the mount's z range (beyond it there is none).
                if dz == 0.0:
                    break
                z_out = z0 - 1e3 * margin if dz < 0.0 else z0 + table.shape[1] / inv_h + 1e3 * margin
                if not _clear(ox, oy, oz, dx, dy, dz, max((z_out - oz) / dz, 0.0), z0, inv_h, table, margin):
                    break
                over[j] = True  # escaped: GONE where it started this step, as the Embree path leaves it
                break
            if not _clear(ox, oy, oz, dx, dy, dz, t_end, z0, inv_h, table, margin):
                break
            px, py, pz = ox + t_end * dx, oy + t_end * dy, oz + t_end * dz
            if on_det:  # the air before the detector absorbs nothing
                o[i, 0], o[i, 1], o[i, 2] = px, py, pz
                if dz > 0.0:
                    kind[i] = _DETECTOR
                    normal[i, 0], normal[i, 1], normal[i, 2] = 0.0, 0.0, -1.0
                over[j] = True
                break
            if mirror[s]:
                break
            k, lam = s, wl[i]
            # The analytic normal (Profile.normal), oriented +z.
            lx, ly = px, py
            g = curv[k] / math.sqrt(max(1.0 - (1.0 + conic[k]) * curv[k] * curv[k] * (lx * lx + ly * ly), 1e-300))
            nx, ny, nz = -g * lx, -g * ly, 1.0
            nn = math.sqrt(nx * nx + ny * ny + nz * nz)
            nx, ny, nz = nx / nn, ny / nn, nz / nn
            cos_dn = dx * nx + dy * ny + dz * nz
            forward = cos_dn >= 0.0
            if absorbs:
                alpha = abef[k, lam] if forward else aaft[k, lam]
                w[i] *= math.exp(-alpha * max(t, 0.0))
            n1 = nbef[k, lam] if forward else naft[k, lam]
            n2 = naft[k, lam] if forward else nbef[k, lam]
            eta = n1 / n2
            # Snell (optics.snell.refract)
            sgn = 1.0 if forward else -1.0
            mx, my, mz = nx * sgn, ny * sgn, nz * sgn
            cos_i = abs(cos_dn)
            sin2_t = eta * eta * max(0.0, 1.0 - cos_i * cos_i)
            tir = sin2_t > 1.0
            cos_t = math.sqrt(max(0.0, 1.0 - sin2_t))
            rx, ry, rz = dx - 2.0 * cos_dn * nx, dy - 2.0 * cos_dn * ny, dz - 2.0 * cos_dn * nz
            if tir:
                tx, ty, tz = rx, ry, rz
            else:
                f = cos_t - eta * cos_i
                tx, ty, tz = eta * dx + f * mx, eta * dy + f * my, eta * dz + f * mz
            tn = max(math.sqrt(tx * tx + ty * ty + tz * tz), 1e-300)
            tx, ty, tz = tx / tn, ty / tn, tz / tn
            r = 1.0 if tir else min(max(reflectance(n1, n2, cos_i, code[k], r_const[k], wavelengths[lam]), 0.0), 1.0)
            if ghosts:
                u = uniform(keys[i], fresnel_dim + count[i]) if keys.shape[0] > 0 else 1.0
                if tir or u < r:  # Tracer._interface: a reflected ray takes the unnormalised mirror direction
                    tx, ty, tz = rx, ry, rz
                if u < r and not tir:
                    reflections[i] += 1
                    slot = 0 if ghost_pair[i, 0] < 0 else 1
                    if ghost_pair[i, slot] < 0:
                        ghost_pair[i, slot] = k
            elif not tir:
                w[i] = w[i] * (1.0 - r)
            o[i, 0], o[i, 1], o[i, 2] = px, py, pz
            d[i, 0], d[i, 1], d[i, 2] = tx, ty, tz
            count[i] += 1
            leaving[i] = True
            left_n[i, 0], left_n[i, 1], left_n[i, 2] = 0.0, 0.0, 0.0
            left_s[i] = k
            if not (math.isfinite(tx) and math.isfinite(ty) and math.isfinite(tz) and math.isfinite(w[i])):
                lost[i] = True
                over[j] = True
                break


CHUNK = 256  # rays per task on every core: enough to spread the reference counts thin, small enough to balance


@njit(cache=True)
def _walk_one_core(work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal, reflections, ghost_pair, lost,
                   keys, ghosts, lens, bore, detector, fresnel_dim, max_optical):
    over = np.zeros(work.shape[0], np.bool_)
    _walk_rays(0, work.shape[0], over, work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal, reflections,
               ghost_pair, lost, keys, ghosts, lens, bore, detector, fresnel_dim, max_optical)
    return over


@njit(cache=True, parallel=True)
def _walk_all_cores(work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal, reflections, ghost_pair, lost,
                    keys, ghosts, lens, bore, detector, fresnel_dim, max_optical):
    over = np.zeros(work.shape[0], np.bool_)
    for c in prange((work.shape[0] + CHUNK - 1) // CHUNK):
        _walk_rays(c * CHUNK, min((c + 1) * CHUNK, work.shape[0]), over, work, o, d, w, wl, left_s, leaving, left_n,
                   count, kind, normal, reflections, ghost_pair, lost, keys, ghosts, lens, bore, detector, fresnel_dim,
                   max_optical)
    return over


_ONE_CORE = [False]


def one_core_per_process() -> None:
    """This process is one of several workers sharing the machine (`lensmount.run.executor`): walk on
    one core. Also what keeps a forked worker out of the threading layer its parent may have
    started (GNU OpenMP is not fork-safe)."""
    _ONE_CORE[0] = True


def walk(work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal, reflections, ghost_pair, lost,
         keys, ghosts, lens, bore, detector, fresnel_dim, max_optical):
    """Carry rays `work` (indices into the arrays) through the glass as far as each step is
    proven (module docstring), updating their state in place like `Tracer.next_event`'s loop.
    Returns (len(work),) bool: the ray's call is over (detector, escaped, or lost on a bad
    number); the others are where a step could not be proven, for Embree. On every core of the
    machine unless `one_core_per_process` was called: the rays are independent, so the result is the same.

    lens: `LensTables`; bore: `clear_bore`; detector: `DetectorPlane`.
    """
    kernel = _walk_one_core if _ONE_CORE[0] or work.shape[0] < THREADED_FROM else _walk_all_cores
    return kernel(work, o, d, w, wl, left_s, leaving, left_n, count, kind, normal, reflections, ghost_pair, lost, keys,
                  ghosts, lens, bore, detector, fresnel_dim, max_optical)


__all__ = ["walk", "LensTables", "DetectorPlane", "clear_bore", "axis_distance", "reflectance", "uniform", "COATING_CODES"]

drop_damaged(globals())  # a damaged cache file is compiled again, not loaded (trace.jit_cache)
