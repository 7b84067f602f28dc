"""OpticStudio's Q-type asphere surface (TYPE QED_TYPE) as a Forbes departure (lensmount.optics.qtype).

How OpticStudio writes one (Thorlabs' ASL5040-UV, saved by OpticStudio in 2020, VERS 200914):

    TYPE QED_TYPE
    CURV c ...          the base curvature, CONI k the base conic
    XDAT 1 t            the form: 0 Qbfs, 1 Qcon (OpticStudio's "Type 0 indicates Qbfs polynomials,
                        and Type 1 indicates Qcon polynomials")
    XDAT 2 N            the number of terms
    XDAT 3 r_n          the normalisation radius, lens units
    XDAT 4 .. 3+N       a_0 .. a_(N-1), lens units

Anything else a Q-type face carries (a PARM, an extra-data entry beyond the N terms) has no reading
here that we could vouch for, so a non-zero one is refused rather than dropped.
"""

from __future__ import annotations

from lensmount.errors import InputError
from lensmount.optics.qtype import FORMS, QType


def qtype_of(zs, unit: float, file) -> QType | None:
    """The Q-type departure of parsed surface `zs` (zemax.ZmxSurface) in mm, None unless TYPE QED_TYPE."""
    if zs.type != "QED_TYPE":
        return None
    where = f"surface {zs.number} (Q-type asphere, QED_TYPE)"
    form, line = zs.xdat.get(1, (0.0, zs.type_line))
    if form not in (0.0, 1.0):
        raise InputError(f"{where} has form {form:g}", file=file, line=line,
                         valid="XDAT 1 = 0 (Qbfs) or 1 (Qcon)")
    count, line = zs.xdat.get(2, (0.0, zs.type_line))
    if count != int(count) or count < 0:
        raise InputError(f"{where} has {count:g} terms", file=file, line=line,
                         valid="XDAT 2: the number of terms, a whole number >= 0")
    r_n, line = zs.xdat.get(3, (0.0, zs.type_line))
    if not r_n > 0.0:
        raise InputError(f"{where} has normalisation radius {r_n:g}", file=file, line=line,
                         valid="XDAT 3 > 0: the normalisation radius")
    n = int(count)
    for k, (value, ln) in sorted(zs.parm.items()):
        if value != 0.0:
            raise InputError(f"{where} has parameter {k} = {value:g}, which lensmount does not read", file=file,
                             line=ln, valid="a Q-type face described by its extra data alone (XDAT 1-3 and its terms)")
    for k, (value, ln) in sorted(zs.xdat.items()):
        if k > 3 + n and value != 0.0:
            raise InputError(f"{where} has extra data {k} = {value:g} beyond its {n} terms (XDAT 4-{3 + n})",
                             file=file, line=ln, valid="the rotationally symmetric Q-type terms only")
    coefficients = tuple(zs.xdat.get(k, (0.0, 0))[0] * unit for k in range(4, 4 + n))
    return QType(FORMS[int(form)], r_n * unit, coefficients)


def qtype_note(q: QType, semi_diameter: float) -> str:
    """What the import note says of a Q-type face; semi_diameter: the largest the file gives (mm)."""
    what = (f"Forbes Q-type asphere ({'Qbfs' if q.form == 'qbfs' else 'Qcon'}, {len(q.coefficients)} terms, "
            f"normalisation radius {q.norm_radius:g} mm)")
    if semi_diameter > q.norm_radius:
        what += (f"; the file's semi-diameter {semi_diameter:g} mm lies beyond it (u up to "
                 f"{semi_diameter / q.norm_radius:.3g}), where the face is the polynomials' extrapolation")
    return what


__all__ = ["qtype_of", "qtype_note"]
