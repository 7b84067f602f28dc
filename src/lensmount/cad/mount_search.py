"""`lensmount init`'s search for a mount that builds: the planner's own alternatives, tried where
its refusal points.

A starting mount.toml (cad.starter) is checked as `regenerate` checks it, with the layout planner
(cad.layout) and the profile checks (cad.checks), no CAD. When they refuse it, the refusal names
what it refused: a field (`seats.element.4`, `lens_edge.semi_diameter_mm.3`,
`spacers.aperture_margin_mm`, ...) and, in its sentence, the elements, surfaces and parts
involved (`lens-3`, `element 4`, `surface 6`, the diaphragm). The alternatives tried are the
planner's options for those lens groups, most specific first:

- the seat of each group involved: shoulder, spacer, ring (retainer) or resting on its neighbour
  (glass), and the front and rear seats of the first and last groups;
- the group's rim (`lens_edge.semi_diameter_mm`): wider by half the edge allowance or by all of
  it, or narrower by a quarter of it, never inside the clear aperture plus contact margin and chamfer;
- its outer faces ground flat from their clear semi-diameter (`lens_edge.flat_faces`);
- and, where the field is a margin, that margin halved (contacts, or the bores above the beam).

The search goes depth first: an alternative that is refused for another reason (another part,
another element, another kind of fault: the sentence with its measurements left out) fixed what
was refused before, so the next refusal is worked on from there; one refused for the same reason
did not, and the next alternative is tried. Every mount is tried once, at most `MAX_TRIES` in
all, so `init` ends in bounded time and either hands over a mount that builds or says why not.
"""

from __future__ import annotations

import copy
import json
import re
from dataclasses import dataclass

from lensmount.errors import InputError
from lensmount.optics.prescription import Prescription

MAX_TRIES = 40   # plans tried after the first ones (each a layout and its profile checks, 0.1-3 s)
MAX_DEPTH = 6    # refusals worked through one after the other on one path
SEATS = ("shoulder", "spacer", "retainer", "glass")


@dataclass(frozen=True)
class Refusal:
    """Why the planner or the checks refused a mount: the error's field, sentence and paragraph."""

    field: str
    message: str
    paragraph: str

    @property
    def kind(self) -> str:
        """The sentence without its measurements: the same fault at the same place, however large."""
        return self.field + "|" + re.sub(r"-?\d+\.\d+(e[-+]?\d+)?", "#", self.message)


def refusal(p: Prescription, mount: dict) -> Refusal | None:
    """What `regenerate` would refuse in this mount.toml at its layout and profile checks (None: it
    builds that far)."""
    from lensmount.cad.checks import check_layout
    from lensmount.cad.layout import plan
    from lensmount.design.mount import parse_mount

    try:
        spec = parse_mount(mount)
        layout = plan(p, spec)
        check_layout(layout, spec, {part.name: part.template.segments() for part in layout.parts})
    except InputError as error:
        return Refusal(error.field or "", error.detail, error.paragraph())
    return None


def find_mount(p: Prescription, starts: list[dict]) -> tuple[dict | None, list[tuple[str, Refusal | None]]]:
    """The first of `starts` that builds, else the first mount that builds among the alternatives
    to their refusals (None when none does); and what was tried on the way ((what, refusal), in
    order; the refusal None for the alternative that built)."""
    tried: list[tuple[str, Refusal]] = []
    seen: set[str] = set()
    refused = []
    for k, mount in enumerate(starts):
        seen.add(_key(mount))
        why = refusal(p, mount)
        if why is None:
            return mount, tried
        tried.append(("the first plan" if k == 0 else f"starting seating {k + 1}", why))
        refused.append((mount, why))
    budget = [MAX_TRIES]
    for mount, why in refused:
        found = _explore(p, mount, why, 1, seen, tried, budget)
        if found is not None:
            return found, tried
    return None, tried


def _explore(p, mount, why, depth, seen, tried, budget) -> dict | None:
    for what, alt in alternatives(p, mount, why):
        key = _key(alt)
        if key in seen:
            continue
        if budget[0] <= 0:
            return None
        seen.add(key)
        budget[0] -= 1
        again = refusal(p, alt)
        if again is None:
            tried.append((what, None))
            return alt
        tried.append((what, again))
        if again.kind != why.kind and depth < MAX_DEPTH:   # it mended what was refused: on from there
            found = _explore(p, alt, again, depth + 1, seen, tried, budget)
            if found is not None:
                return found
    return None


def _key(mount: dict) -> str:
    return json.dumps(mount, sort_keys=True)


def alternatives(p: Prescription, mount: dict, why: Refusal) -> list[tuple[str, dict]]:
    """The planner's options for the lens groups the refusal involves, most specific first:
    (what was changed, the changed mount.toml)."""
    from lensmount.cad.layout import group_rim
    from lensmount.design.mount import parse_mount

    groups = p.lens_groups()
    first = [1]
    for g in groups[:-1]:
        first.append(first[-1] + len(g) - 1)
    edge = mount["lens_edge"]
    allowance, contact, chamfer = edge["allowance_mm"], edge["contact_margin_mm"], edge["chamfer_mm"]
    spec_edge = parse_mount(mount).lens_edge
    stop = p.stop_index
    out: list[tuple[str, dict]] = []

    def changed(what: str, edit) -> None:
        alt = copy.deepcopy(mount)
        edit(alt)
        out.append((what, alt))

    def seat_moves(k: int) -> None:
        if k == 0 or groups[k - 1][-1] <= stop <= groups[k][0]:   # the diaphragm's gap has spacers
            return
        n = str(first[k])
        now = mount["seats"].get("element", {}).get(n, mount["seats"]["default"])
        for seat in SEATS:
            if seat != now:
                changed(f"element {n} seated on a {seat}" if seat != "glass" else f"element {n} resting on its "
                        "neighbour", lambda m, n=n, seat=seat: m["seats"].setdefault("element", {}).update({n: seat}))

    def end_moves(k: int) -> None:   # the first group's front seat, the last group's rear seat
        for side, which in (("front", 0), ("rear", len(groups) - 1)):
            if k == which:
                other = "shoulder" if mount["seats"][side] == "retainer" else "retainer"
                changed(f"{side} seat a {other}", lambda m, side=side, other=other: m["seats"].update({side: other}))

    def rim_moves(k: int, wider: bool) -> None:
        g = groups[k]
        rim = group_rim(p, g, first[k], spec_edge)
        floor = max(float(p.surfaces[i].clear_semi_diameter) for i in g) + contact + chamfer + 0.01
        sizes = (rim + 0.5 * allowance, rim + allowance) if wider else (max(rim - 0.25 * allowance, floor),)
        for r in sizes:
            if abs(r - rim) > 1e-6:
                numbers = {str(first[k] + j): round(r, 3) for j in range(len(g) - 1)}
                changed(f"element {first[k]}'s rim {r:.3f} mm (was {rim:.3f} mm)",
                        lambda m, numbers=numbers: m["lens_edge"].setdefault("semi_diameter_mm", {}).update(numbers))

    def flat_moves(k: int) -> None:
        flats = set(edge.get("flat_faces", ()))
        for i in (groups[k][0], groups[k][-1]):
            if i + 1 not in flats and p.surfaces[i].curvature != 0.0:
                changed(f"surface {i + 1} ground flat from its clear semi-diameter",
                        lambda m, i=i: m["lens_edge"].update(flat_faces=sorted(flats | {i + 1})))

    involved = _groups_involved(p, why, first)
    m = re.fullmatch(r"seats\.element\.(\d+)", why.field)
    if m is not None and int(m.group(1)) in first:
        seat_moves(first.index(int(m.group(1))))
    narrow_first = why.field.startswith("lens_edge.semi_diameter_mm")   # a rim too wide for its faces
    for k in involved:
        seat_moves(k)
        end_moves(k)
        rim_moves(k, wider=not narrow_first)
        flat_moves(k)
        rim_moves(k, wider=narrow_first)
    margins = {"lens_edge.contact_margin_mm": ("lens_edge", "contact_margin_mm"),
               "spacers.aperture_margin_mm": ("spacers", "aperture_margin_mm")}
    if why.field in margins:
        table, key = margins[why.field]
        value = mount[table].get(key)
        if value is not None and value > 0.05:
            changed(f"{why.field} {value / 2:g} mm (was {value:g} mm)",
                    lambda m, table=table, key=key, v=round(value / 2, 3): m[table].update({key: v}))
    return out


def _groups_involved(p: Prescription, why: Refusal, first: list[int]) -> list[int]:
    """Indices of the lens groups a refusal names (its elements, surfaces, the diaphragm's neighbours),
    the later first (a seat belongs to the group behind its gap); every group when it names none."""
    groups = p.lens_groups()

    def of_element(n: int) -> int | None:
        return next((k for k in range(len(groups) - 1, -1, -1) if first[k] <= n), None) \
            if 1 <= n < first[-1] + len(groups[-1]) - 1 else None

    text = why.message + " " + why.field
    found: set[int] = set()
    for n in re.findall(r"(?:lens-|element |semi_diameter_mm\.|seats\.element\.)(\d+)", text):
        k = of_element(int(n))
        if k is not None:
            found.add(k)
    for n in re.findall(r"surface (\d+)|surface\[(\d+)\]", text):
        i = int(n[0] or n[1]) - 1
        found |= {k for k, g in enumerate(groups) if g[0] <= i <= g[-1]}
        found |= {k for k in range(len(groups) - 1) if groups[k][-1] < i < groups[k + 1][0]} | \
                 {k + 1 for k in range(len(groups) - 1) if groups[k][-1] < i < groups[k + 1][0]}
    if "diaphragm" in text or "stop" in text:
        stop = p.stop_index
        found |= {k for k, g in enumerate(groups) if g[0] - 1 <= stop <= g[-1] + 1}
        if stop < groups[0][0]:
            found.add(0)
        if stop > groups[-1][-1]:
            found.add(len(groups) - 1)
        found |= {k for k in range(len(groups) - 1) if groups[k][-1] <= stop <= groups[k + 1][0]} | \
                 {k + 1 for k in range(len(groups) - 1) if groups[k][-1] <= stop <= groups[k + 1][0]}
    return sorted(found or range(len(groups)), reverse=True)


__all__ = ["find_mount", "refusal", "alternatives", "Refusal", "MAX_TRIES"]
