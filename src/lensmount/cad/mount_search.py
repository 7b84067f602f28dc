"""`lensmount init`'s search for a mount that builds: the planner's own alternatives, tried where
its refusal points.

A starting mount.toml (cad.starter) is checked as `regenerate` checks it: the layout planner
(cad.layout) and the profile checks (cad.checks), then the solids and their tessellation
(cad.assembly) for a plan those pass. When they refuse it, the refusal names
what it refused: a field (`seats.element.4`, `lens_edge.semi_diameter_mm.3`,
`spacers.aperture_margin_mm`, ...) and, in its sentence, the elements, surfaces and parts
involved (`lens-3`, `element 4`, `surface 6`, the diaphragm). The alternatives tried are the
planner's options for those lens groups, most specific first:

- the seat of each group involved: shoulder, spacer, ring (retainer) or resting on its neighbour
  (glass), and the front and rear seats of the first and last groups (retainer, shoulder, or the
  element bonded into the bore by its edge when the beam leaves no annulus on its face for either);
- the group's rim (`lens_edge.semi_diameter_mm`): wider by half the edge allowance or by all of
  it, or narrower by a quarter of it, never inside the clear aperture plus contact margin and chamfer
  (and all the groups named wider together: a spacer's bore follows the narrower neighbour);
- its outer faces ground flat from their clear semi-diameter (`lens_edge.flat_faces`);
- the field's own number halved where the planner asks for a smaller or thinner one (a margin, a
  ring), an element too thin at its edge with its chamfers halved (`lens_edge.chamfer_mm`: a flat
  window a quarter of a millimetre thick loses most of its edge to them), and where the diaphragm is
  involved, its plate thinner (never below `checks.min_thickness_mm`) and its knife edge bevelled on
  the other side.

The search goes depth first: an alternative refused for a reason not met on its way there (another
part, element or kind of fault: the sentence with its measurements left out) mended what was
refused, and its own refusal is worked on at once, with a share of the plans left, before the next
alternatives (a lens with several tight gaps is mended one gap after the other); one refused for a
reason already met on its way is not worked on. Every mount is tried once, at most `MAX_TRIES` in all, so
`init` ends in bounded time and either hands over a mount that builds or says why not.
"""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Iterable
from dataclasses import dataclass

from lensmount.cad.checks import check_layout
from lensmount.cad.layout import plan
from lensmount.cad.lens_groups import group_rim
from lensmount.design.mount import parse_mount
from lensmount.errors import InputError
from lensmount.optics.prescription import Prescription

MAX_TRIES = 40   # plans tried after the first ones (each a layout and its profile checks, 0.1-3 s)
MAX_DEPTH = 6    # refusals mended one after the other on one path
SEATS = ("shoulder", "spacer", "retainer", "glass")
END_SEATS = ("retainer", "shoulder", "bonded")   # bonded last: a seat on the face is preferred where one fits


@dataclass(frozen=True)
class Refusal:
    """Why the planner or the checks refused a mount: the error's field, sentence and paragraph."""

    field: str
    message: str
    paragraph: str
    valid: str = ""

    @property
    def kind(self) -> str:
        """The sentence without its measurements: the same fault at the same place, however large."""
        return self.field + "|" + re.sub(r"-?\d+\.\d+(e[-+]?\d+)?", "#", self.message)


def refusal(p: Prescription, mount: dict) -> Refusal | None:
    """What `regenerate` would refuse in this mount.toml (None: it builds): its layout and profile
    checks, and when they pass, the CAD kernel's solids and their tessellation, as regenerate makes
    them (cad.assembly; init writes no user template or STEP part, the rest of regenerate's assembly).
    Only a plan the checks pass reaches the kernel, so a search builds solids about once."""
    from lensmount.cad.assembly import build_parts, tessellate  # lazy: the CAD kernel loads only for a plan that passes its checks

    try:
        spec = parse_mount(mount)
        layout = plan(p, spec)
        check_layout(layout, spec, {part.name: part.template.segments() for part in layout.parts})
    except InputError as error:
        return Refusal(error.field or "", error.detail, error.paragraph(), error.valid or "")
    try:
        tessellate(build_parts(layout, spec), spec, layout)
    except InputError as error:   # the solids: the kernel's own refusals (an invalid solid, ...)
        return Refusal(error.field or "", error.detail, error.paragraph(), error.valid or "")
    return None


def find_mount(p: Prescription, starts: Iterable[dict]) -> tuple[dict | None, list[tuple[str, Refusal | None]]]:
    """The first of `starts` that builds (made only as far as needed), else the first mount that
    builds among the alternatives to their refusals (None when none does); and what was tried on the
    way ((what, refusal), in order; the refusal None for the alternative that built)."""
    tried: list[tuple[str, Refusal | None]] = []
    refused = []
    seen: set[str] = set()
    for k, mount in enumerate(starts):
        if _key(mount) in seen:
            continue
        seen.add(_key(mount))
        why = refusal(p, mount)
        if why is None:
            return mount, tried
        tried.append(("the first plan" if k == 0 else f"starting seating {k + 1}", why))
        refused.append((mount, why))
    left = MAX_TRIES
    for k, (mount, why) in enumerate(refused):   # each starting seating its share of the plans
        found, used = _explore(p, mount, why, [], left // (len(refused) - k), seen, {why.kind}, tried)
        left -= used
        if found is not None or left <= 0:
            return found, tried
    return None, tried


def _explore(p, mount, why, path, budget, seen, kinds, tried) -> tuple[dict | None, int]:
    """Depth first from a refused mount, at most `budget` plans: (the mount that builds or None, plans
    used). An alternative refused for a reason not met on its path (`kinds`) is worked on at once, with
    a third of what is left (at least 4 plans), then the next alternatives are tried."""
    used = 0
    for what, alt in alternatives(p, mount, why):
        key = _key(alt)
        if key in seen:
            continue
        if used >= budget:
            break
        seen.add(key)
        used += 1
        again = refusal(p, alt)
        tried.append((", ".join(path + [what]), again))
        if again is None:
            return alt, used
        if again.kind not in kinds and len(path) + 1 < MAX_DEPTH:   # it mended what was refused
            share = min(budget - used, max(4, (budget - used) // 3))
            found, n = _explore(p, alt, again, path + [what], share, seen, kinds | {again.kind}, tried)
            used += n
            if found is not None:
                return found, used
    return None, used


def _key(mount: dict) -> str:
    return json.dumps(mount, sort_keys=True)


def alternatives(p: Prescription, mount: dict, why: Refusal) -> list[tuple[str, dict]]:
    """The planner's options for the lens groups the refusal involves, most specific first:
    (what was changed, the changed mount.toml). None for a lens with mirrors: its cells in a straight
    barrel (cad.catadioptric) have no seats or rims to choose."""
    if p.has_mirrors:
        return []

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
                for other in END_SEATS:
                    if other != mount["seats"][side]:
                        changed(f"{side} seat a {other}" if other != "bonded" else f"{side} element bonded by its edge",
                                lambda m, side=side, other=other: m["seats"].update({side: other}))

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

    def margin_move(table: str, key: str, least: float) -> None:   # halved, not below `least`
        value = mount[table].get(key)
        if value is not None and max(value / 2, least) < value - 1e-9:
            less = round(max(value / 2, least), 3)
            changed(f"{table}.{key} {less:g} mm (was {value:g} mm)", lambda m: m[table].update({key: less}))

    min_t = mount["checks"]["min_thickness_mm"]
    named, by_stop = _named(p, why, first)
    involved = sorted(named | by_stop or set(range(len(groups))), reverse=True)
    # the gaps whose seat may be what was refused: between two named groups first, then beside one
    gaps = sorted((k for k in range(1, len(groups)) if {k - 1, k} & named or not named | by_stop),
                  key=lambda k: (not {k - 1, k} <= named, -k))
    asked = re.fullmatch(r"seats\.element\.(\d+)", why.field)
    if asked is not None and int(asked.group(1)) in first:
        seat_moves(first.index(int(asked.group(1))))
    # what the refusal's field asks for first, then the rest of the planner's options for those groups
    table, _, key = why.field.partition(".")
    if re.search(r"\b(smaller|thinner)\b", why.valid) and isinstance(mount.get(table, {}).get(key), float):
        margin_move(table, key, min_t if "thickness" in key else 0.05)   # the planner asks for less of it
    if " is too thin" in why.message:   # an element's edge: its protective chamfers take glass from it
        margin_move("lens_edge", "chamfer_mm", 0.0)
    if "diaphragm" in why.message:   # its plate thinner, its knife edge's bevel on the other side
        margin_move("diaphragm", "thickness_mm", min_t)
        side = "front" if mount["diaphragm"].get("bevel_side", "rear") == "rear" else "rear"
        changed(f"the diaphragm's bevel on its {side} side", lambda m: m["diaphragm"].update(bevel_side=side))
    narrow_first = why.field.startswith("lens_edge.semi_diameter_mm")   # a rim too wide for its faces
    for k in gaps:
        seat_moves(k)
    for k in involved:
        end_moves(k)
    if len(involved) > 1 and not narrow_first:   # a spacer's or ring's bore follows the narrower neighbour
        rims = {str(first[k] + j): round(group_rim(p, groups[k], first[k], spec_edge) + 0.5 * allowance, 3)
                for k in involved for j in range(len(groups[k]) - 1)}
        changed(f"elements {', '.join(sorted(rims, key=int))} rims wider by {0.5 * allowance:.3f} mm",
                lambda m: m["lens_edge"].setdefault("semi_diameter_mm", {}).update(rims))
    for k in involved:
        rim_moves(k, wider=not narrow_first)
        flat_moves(k)
        rim_moves(k, wider=narrow_first)
    return out


def _named(p: Prescription, why: Refusal, first: list[int]) -> tuple[set[int], set[int]]:
    """The lens groups a refusal names by their elements or surfaces, and those beside the stop
    when it names the diaphragm or the stop (indices into p.lens_groups())."""
    groups = p.lens_groups()
    last = first[-1] + len(groups[-1]) - 2   # the last element's number
    text = why.message + " " + why.field
    named: set[int] = set()
    for n in re.findall(r"(?:lens-|element |semi_diameter_mm\.|seats\.element\.)(\d+)", text):
        if 1 <= int(n) <= last:
            named.add(max(k for k in range(len(groups)) if first[k] <= int(n)))
    for a, b in re.findall(r"surface (\d+)|surface\[(\d+)\]", text):
        named |= _beside(groups, int(a or b) - 1)
    return named, (_beside(groups, p.stop_index) if "diaphragm" in text or "stop" in text else set())


def _beside(groups, i: int) -> set[int]:
    """The group whose face surface i is, or the groups on either side of the air it lies in."""
    inside = {k for k, g in enumerate(groups) if g[0] <= i <= g[-1]}
    if inside:
        return inside
    return {k for k, g in enumerate(groups) if g[-1] < i and (k + 1 == len(groups) or i < groups[k + 1][0])} | \
           {k for k, g in enumerate(groups) if i < g[0] and (k == 0 or groups[k - 1][-1] < i)}


__all__ = ["find_mount", "refusal", "alternatives", "Refusal", "MAX_TRIES"]
