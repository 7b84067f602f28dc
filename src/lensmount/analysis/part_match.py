"""Which part of one revision is which part of another: matched by what they are, not by their names.

A mount's parts are numbered in order (`vane-1` … `vane-5`, `spacer-2`), so an edit that removes one
renumbers the rest: with three vanes fewer, the new `vane-3` is the piece of metal the old revision
called `vane-5`. Per-part verdicts must compare the same piece of metal, so parts are matched by kind
and place: within one kind, in order along the axis, the pairing that moves the parts least (the sum
of the shifts of their axial and radial extents, mm). Every part of the kind with fewer parts is
paired, so a part that moved a little (or grew: the one hood made longer) is still the same part; the
other kind's leftovers are the parts that went or came. Runs that did not record their parts' extents
(an older lensmount) are matched by name.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class PartMatch:
    """pairs : (old name, new name) of the same part; removed : old parts with no counterpart;
    added : new parts with no counterpart."""

    pairs: list[tuple[str, str]] = field(default_factory=list)
    removed: list[str] = field(default_factory=list)
    added: list[str] = field(default_factory=list)


def _shift(a: dict, b: dict) -> float:
    """How far part a is from part b: the shifts of the ends of its axial and radial extents (mm)."""
    return sum(abs(x - y) for key in ("z_mm", "r_mm") for x, y in zip(a[key], b[key]))


def _along_axis(parts: dict[str, dict], kind: str) -> list[str]:
    return sorted((n for n, p in parts.items() if p["kind"] == kind),
                  key=lambda n: (sum(parts[n]["z_mm"]), sum(parts[n]["r_mm"]), n))


def _pair_in_order(short: list[str], long: list[str], cost) -> list[tuple[int, int]]:
    """Every item of `short` paired with one of `long`, both in axial order, order kept, least total cost
    (dynamic programming over (items of short placed, items of long passed))."""
    n, m = len(short), len(long)
    inf = float("inf")
    best = [[inf] * (m + 1) for _ in range(n + 1)]
    took = [[False] * (m + 1) for _ in range(n + 1)]
    best[0] = [0.0] * (m + 1)
    for i in range(1, n + 1):
        for j in range(i, m + 1):
            skip, pair = best[i][j - 1], best[i - 1][j - 1] + cost(i - 1, j - 1)
            best[i][j], took[i][j] = (pair, True) if pair <= skip else (skip, False)
    pairs, i, j = [], n, m
    while i > 0:
        if took[i][j]:
            pairs.append((i - 1, j - 1))
            i -= 1
        j -= 1
    return pairs[::-1]


def match_parts(old: dict[str, dict] | None, new: dict[str, dict] | None,
                old_names: list[str], new_names: list[str]) -> PartMatch:
    """Match the parts of two runs. old, new : `TaggedMesh.part_extents` as the runs' summaries hold it
    (None: not recorded); old_names, new_names : further names to account for (the runs' per-part
    channels, e.g. `direct`), matched by name when the extents do not know them."""
    pairs: list[tuple[str, str]] = []
    old, new = (old or {}), (new or {})
    if old and new:
        for kind in dict.fromkeys(p["kind"] for p in [*old.values(), *new.values()]):
            a, b = _along_axis(old, kind), _along_axis(new, kind)
            if len(a) <= len(b):
                pairs += [(a[i], b[j]) for i, j in _pair_in_order(a, b, lambda i, j: _shift(old[a[i]], new[b[j]]))]
            else:
                pairs += [(a[i], b[j]) for j, i in _pair_in_order(b, a, lambda j, i: _shift(old[a[i]], new[b[j]]))]
        known_old, known_new = set(old), set(new)
    else:
        known_old = known_new = set()
    rest_old = [n for n in dict.fromkeys([*old, *old_names]) if n not in known_old]
    rest_new = [n for n in dict.fromkeys([*new, *new_names]) if n not in known_new]
    pairs += [(n, n) for n in rest_old if n in rest_new]
    paired_old, paired_new = {p[0] for p in pairs}, {p[1] for p in pairs}
    removed = [n for n in dict.fromkeys([*old, *old_names]) if n not in paired_old]
    added = [n for n in dict.fromkeys([*new, *new_names]) if n not in paired_new]
    return PartMatch(pairs, removed, added)


__all__ = ["PartMatch", "match_parts"]
