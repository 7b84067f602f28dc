"""The glass of a .zmx GLAS line: which step of lensmount's glass resolution finds it.

    GLAS name | MIRROR | ___BLANK a b n_d V_d | 6-digit code; GLAS ... 2 k is a pickup;
    GLAS name 4 ... dn dv: the catalogue glass with offsets (a model glass). The name is
    resolved by lensmount.optics.glass.resolve_glass; the line's own n_d and V_d come last,
    and Zemax's 1.5/40 placeholders are no data.
"""

from __future__ import annotations

import math
import re

from lensmount.errors import InputError
from lensmount.optics.glass import (CATALOGUES, nearest_glass_names, refractive_index, resolve_glass,
                                    searched_catalogues)
from lensmount.optics.prescription import AIR

_SIX_DIGIT = re.compile(r"^(\d{3})(\d{3})$")
_D_LINE, _F_LINE, _C_LINE = 0.5875618, 0.4861327, 0.6562725


def material(zs, medium: str, catalogues, user, file) -> tuple[str, tuple[str, str] | None]:
    """The lensmount material for a GLAS line, and the note (kind, what) saying which step found it: the
    file's own model glass; a glass code; the name in the user's catalogues, the built-in ones,
    the table of legacy glasses or as a legacy name's successor (lensmount.optics.glass.
    resolve_glass); the GLAS line's n_d and V_d when the name is in none of them."""
    if zs.mirror:
        return medium, None
    name = zs.glass
    if name.upper() == AIR:
        return AIR, None
    args = zs.glass_args
    pickup = f" (picked up from surface {args[1]})" if len(args) > 1 and args[0] == "2" else ""
    nd_vd = _file_nd_vd(args, model=name.upper() == "___BLANK")
    if name.upper() == "___BLANK":
        if nd_vd is None:
            raise InputError(f"surface {zs.number} has a model glass without n_d and V_d", file=file,
                             line=zs.glass_line, valid="GLAS ___BLANK 1 0 n_d V_d ... with n_d > 1 and V_d >= 0")
        constant = " (V_d = 0: Zemax's constant index, no dispersion)" if nd_vd[1] == 0 else ""
        return _model(*nd_vd), ("imported", f"the file's model glass n_d {nd_vd[0]:g}, "
                                          f"V_d {nd_vd[1]:g}{constant}{pickup}")
    six = _SIX_DIGIT.match(name)
    if six:
        nd, vd = 1.0 + int(six.group(1)) / 1000.0, int(six.group(2)) / 10.0
        return _model(nd, vd), ("substituted", f"glass code {name} -> model glass {nd:g}/{vd:g}")
    found = resolve_glass(name, user)
    offset = _offset(args)
    if found is not None and offset is not None:
        # OpticStudio's material offset (GLAS name 4 ... dn dv): the prescription's n_d and V_d are the
        # catalogue's plus the offsets, which a model glass carries
        nd, vd = _nd_vd(found.material)
        nd, vd = nd + offset[0], vd + offset[1]
        return _model(nd, vd), ("substituted", f"glass {name} ({found.step}) with the file's offsets "
                                          f"n_d {offset[0]:+g}, V_d {offset[1]:+g} -> model glass n_d {nd:.6g}, "
                                          f"V_d {vd:.6g}{pickup}")
    if found is not None and not found.substituted:
        material = _prefer_catalogue(found.material, catalogues) if catalogues and ":" not in found.material \
            else found.material
        return material, ("imported", f"glass {name}: {found.step}{pickup}")
    if found is not None:
        return found.material, ("substituted", f"glass {name} -> {found.material} ({found.step})"
                                          f"{pickup}")
    if nd_vd is not None:
        return _model(*nd_vd), ("substituted", f"glass {name} is in none of {searched_catalogues(user)} "
                                          f"-> model glass n_d {nd_vd[0]:g}, V_d {nd_vd[1]:g} from the GLAS line")
    placeholder = _is_placeholder(args)
    near = nearest_glass_names(name, user)
    raise InputError(
        f"surface {zs.number}: unknown glass '{name}', searched {searched_catalogues(user)}; "
        + ("the GLAS line carries only Zemax's 1.5/40 placeholders (written when OpticStudio had no data for "
           "the glass), not the glass's n_d and V_d" if placeholder else "the GLAS line gives no n_d and V_d"),
        file=file, line=zs.glass_line,
        valid=(f"a near name ({', '.join(near)}), " if near else "")
        + "a Zemax .agf catalogue holding it (lens.toml glass_catalogs, or --glass-catalog), or real n_d and "
          "V_d on the GLAS line")


def _file_nd_vd(args, model: bool = False) -> tuple[float, float] | None:
    """n_d, V_d from a GLAS line, None where it carries none or (for a named glass) Zemax's
    placeholders; a model glass's 1.5/40 is the designer's."""
    try:
        nd, vd = float(args[2]), float(args[3])
    except (IndexError, ValueError):
        return None
    if not model and _is_placeholder(args):
        return None
    return (nd, vd) if 1.0 < nd < math.inf and 0.0 <= vd < math.inf else None


def _offset(args) -> tuple[float, float] | None:
    """(delta n_d, delta V_d) of a GLAS line in OpticStudio's offset mode (4), None without offsets."""
    if not args or args[0] != "4":
        return None
    try:
        dn, dv = float(args[8]), float(args[9])
    except (IndexError, ValueError):
        return None
    return (dn, dv) if (dn, dv) != (0.0, 0.0) and math.isfinite(dn) and math.isfinite(dv) else None


def _nd_vd(material: str) -> tuple[float, float]:
    nd, nf, nc = (float(refractive_index(material, wl)) for wl in (_D_LINE, _F_LINE, _C_LINE))
    return nd, (nd - 1.0) / (nf - nc)


def _is_placeholder(args) -> bool:
    """1.5/40 is what Zemax writes on a GLAS line when it has no data for the glass (its defaults):
    no information."""
    try:
        return (float(args[2]), float(args[3])) == (1.5, 40.0)
    except (IndexError, ValueError):
        return False


def _model(nd: float, vd: float) -> str:
    # V_d = 0 is Zemax's constant index, which lensmount's model glass "n_d/0" means too
    return f"{nd:.12g}/{vd:.12g}"


def _prefer_catalogue(name: str, catalogues: list[str]) -> str:
    """Keep the plain name unless a GCAT catalogue holds a different glass of that name."""
    known = [c for c in catalogues if c.lower() in (k.lower() for k in CATALOGUES)]
    if not known:
        return name
    for cat in known:
        prefixed = f"{cat.upper()}:{name}"
        try:
            n_pref = float(refractive_index(prefixed, _D_LINE))
        except InputError:
            continue
        try:
            n_plain = float(refractive_index(name, _D_LINE))
        except InputError:
            return prefixed
        return name if n_plain == n_pref else prefixed
    return name


__all__ = ["material"]
