"""Refractive indices from glass catalogues (never typed by hand).

Names: `N-BK7` (searched in the user's catalogues, then Schott, Ohara, Hoya, CDGM, Sumita,
Hikari in that order), `SCHOTT:N-BK7` (one catalogue; a user catalogue is named by its .agf
file's stem, `MYGLASS:B270`), or a model glass `1.5168/64.17` (n_d / V_d, with a two-term
Cauchy dispersion through n_F - n_C = (n_d - 1)/V_d; V_d = 0 is Zemax's constant index,
no dispersion). Air is 1.0 at every wavelength: lensmount models no air dispersion (a < 3e-4
index error, which shifts a 360 mm focal length by far less than the 0.01 % we check).

How a name found in a lens file is resolved, in order (`resolve_glass`, each step said by
`lensmount inspect`): the user's catalogues in Zemax's .agf format (`optics.io.agf.register_catalogue`:
lens.toml `glass_catalogs`, `--glass-catalog`); the built-in catalogues (opticalglass); a
table of legacy and technical glasses the catalogues lack (`legacy_glasses.csv`: Schott's
B 270 and D 263 T eco, obsolete Schott glasses, LZOS, with n_d and V_d from the refractiveindex.info
database, CC0, written by tools/legacy_glasses.py, each row naming its source; used as a model
glass); a legacy or moulding name's catalogue successor (`successor`: BK7 -> N-BK7).

Besides the vendor catalogues, fused silica (Zemax's MISC catalogue name `SILICA`, also
`F_SILICA`, `FUSED_SILICA`, and Corning's 7980, `C79-80`) uses Malitson's Sellmeier fit (J. Opt. Soc. Am. 55, 1205,
1965; 0.21-3.71 µm), the formula every optics package uses for it.
"""

from __future__ import annotations

import csv
import difflib
import hashlib
import functools
import logging
import re
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from lensmount.errors import InputError
from lensmount.optics.prescription import AIR

CATALOGUES = ("Schott", "Ohara", "Hoya", "CDGM", "Sumita", "Hikari")
# Zemax's MISC and CORNING names for fused silica (C79-80: Corning HPFS 7980)
_FUSED_SILICA_NAMES = ("SILICA", "F_SILICA", "FUSED_SILICA", "FUSEDSILICA", "MISC:SILICA", "C79-80", "CORNING:C79-80",
                       "C7980")
_MALITSON_B = (0.6961663, 0.4079426, 0.8974794)
_MALITSON_C = (0.0684043**2, 0.1162414**2, 9.896161**2)  # µm^2
MODEL_GLASS = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*/\s*(\d+(?:\.\d+)?)\s*$")
_LAMBDA_D, _LAMBDA_F, _LAMBDA_C = 0.5875618, 0.4861327, 0.6562725
_LEGACY_TABLE = Path(__file__).with_name("legacy_glasses.csv")


@dataclass(frozen=True)
class Resolved:
    """A glass name resolved: the material lensmount uses and the step that found it."""

    material: str
    step: str
    substituted: bool = False  # another glass (or a model of it) stands in for the name


class CatalogueGlass(Protocol):
    """A glass of a user's catalogue, as its reader made it (`optics.io.agf.AgfGlass`)."""

    def index(self, wavelength_um) -> np.ndarray: ...


# NAME -> (path, {GLASS: CatalogueGlass}); see add_catalogue. Process-wide, so that a material
# `NAME:GLASS` means the same glass wherever the lens goes (the tracer's forked workers too).
_USER_CATALOGUES: dict[str, tuple[str, Mapping[str, CatalogueGlass]]] = {}


def add_catalogue(path: Path, glasses: Mapping[str, CatalogueGlass]) -> str:
    """Make a user catalogue's glasses (upper-case name → glass) known by name; returns the
    catalogue's name, by which `NAME:GLASS` selects one of them: the file's stem, upper case (with
    a digest of the path added when another file of that stem is already known in this process,
    so that each name means one file). The same file again replaces what it held."""
    path = Path(path).resolve()
    name = path.stem.upper()
    if name in (c.upper() for c in CATALOGUES):
        raise InputError(f"the glass catalogue {path.name} has the name of a built-in one ({name})", file=str(path),
                         valid="another file name for the user's catalogue (its glasses are named NAME:GLASS)")
    known = _USER_CATALOGUES.get(name)
    if known is not None and known[0] != str(path):
        name = f"{name}-{hashlib.sha256(str(path).encode()).hexdigest()[:8].upper()}"
    _USER_CATALOGUES[name] = (str(path), glasses)   # replaced: the file may have changed since
    return name


def resolve_glass(name: str, user: tuple[str, ...] = ()) -> Resolved | None:
    """Where a glass name is found (module docstring), None if nowhere. `user`: the names of the
    registered user catalogues (add_catalogue) a plain name is looked up in first."""
    name = name.strip()
    if ":" in name:
        cat, glass = (x.strip() for x in name.split(":", 1))
        if cat.upper() in _USER_CATALOGUES:
            return (Resolved(f"{cat.upper()}:{glass.upper()}", f"user catalogue {_USER_CATALOGUES[cat.upper()][0]}")
                    if glass.upper() in _USER_CATALOGUES[cat.upper()][1] else None)
    else:
        for cat in user:
            path, glasses = _USER_CATALOGUES[cat]
            if name.upper() in glasses:
                return Resolved(f"{cat}:{name.upper()}", f"user catalogue {path}")
    if name.upper() in _FUSED_SILICA_NAMES:
        return Resolved(name, "fused silica (Malitson's Sellmeier fit)")
    found = _find_catalogue_glass(name)
    if found is not None:
        return Resolved(name, f"built-in catalogue {found.catalog_name()}")
    row = _legacy().get(re.sub(r"[\s_-]", "", name.upper()))
    if row is not None:
        return Resolved(_model(row["n_d"], row["V_d"]), f"{row['maker']} {row['name']} from the table of legacy and "
                        f"technical glasses ({row['source']}): model glass n_d {row['n_d']}, V_d {row['V_d']}", True)
    new = successor(name)
    if new is not None:
        return Resolved(new, "a legacy or moulding name: its catalogue successor", True)
    return None


def nearest_glass_names(name: str, user: tuple[str, ...] = (), n: int = 3) -> list[str]:
    """The catalogue names closest to `name` (for an unknown glass's message)."""
    names = {g for cat in user for g in _USER_CATALOGUES[cat][1]}
    for cat in CATALOGUES:
        names.update(_catalogue_names(cat))
    names.update(r["name"] for r in _legacy().values())
    return difflib.get_close_matches(name.strip().upper(), sorted(names), n=n, cutoff=0.6)


def searched_catalogues(user: tuple[str, ...] = ()) -> str:
    """The catalogues `resolve_glass` searches, in order, for an error message."""
    names = [f"{n} ({_USER_CATALOGUES[n][0]})" for n in user]
    return ", ".join(names + list(CATALOGUES) + ["the table of legacy glasses"])


@functools.lru_cache(maxsize=None)
def _legacy() -> dict[str, dict]:
    out: dict[str, dict] = {}
    with _LEGACY_TABLE.open(encoding="utf-8", newline="") as fh:
        for row in csv.DictReader(fh):
            for key in [row["name"], *row["aliases"].split()]:
                out.setdefault(re.sub(r"[\s_-]", "", key.upper()), row)  # the table lists Schott's first
    return out


def _model(nd, vd) -> str:
    return f"{float(nd):.6g}/{float(vd):.6g}"


@functools.lru_cache(maxsize=None)
def _catalogue_glass(name: str, catalogue: str):
    from opticalglass import glassfactory  # lazy: keeps lensmount --help from loading opticalglass and pandas

    logging.getLogger("opticalglass").setLevel(logging.ERROR)
    with warnings.catch_warnings():  # the catalogue loader's pandas deprecation notices are not the user's business
        warnings.simplefilter("ignore")
        return glassfactory.create_glass(name, catalogue)


@functools.lru_cache(maxsize=None)
def medium(name: str):
    """A callable n(wavelength_um) for a material name; raises InputError if unknown."""
    if name.strip().upper() == AIR:
        return lambda wl: np.ones_like(np.asarray(wl, dtype=np.float64))
    if name.strip().upper() in _FUSED_SILICA_NAMES:
        return _fused_silica
    m = MODEL_GLASS.match(name)
    if m:
        nd, vd = float(m.group(1)), float(m.group(2))
        if nd < 1.0:
            raise InputError(f"model glass '{name}' has n_d < 1",
                             field="material", valid="n_d/V_d with n_d >= 1 and V_d >= 0, e.g. 1.5168/64.17")
        if vd == 0.0:  # Zemax's model glass with V_d = 0: a constant index
            return lambda wl: np.full(np.shape(wl), nd)
        # Cauchy n = a + b / lambda^2 through n_d and n_F - n_C.
        b = (nd - 1.0) / vd / (1.0 / _LAMBDA_F**2 - 1.0 / _LAMBDA_C**2)
        a = nd - b / _LAMBDA_D**2
        return lambda wl: a + b / np.asarray(wl, dtype=np.float64) ** 2
    cat, _, glass_name = name.strip().upper().rpartition(":")
    if cat in _USER_CATALOGUES and glass_name in _USER_CATALOGUES[cat][1]:
        return _USER_CATALOGUES[cat][1][glass_name].index
    resolved = resolve_glass(name)
    if resolved is not None and resolved.material != name.strip():
        return medium(resolved.material)
    glass = _find_catalogue_glass(name)
    if glass is None:
        near = nearest_glass_names(name)
        raise InputError(f"unknown glass '{name}' (searched {searched_catalogues()})", field="material",
                         valid=(f"a near name: {', '.join(near)}; or " if near else "")
                         + "a glass of those catalogues (optionally 'SCHOTT:N-BK7'), a user catalogue "
                         "(glass_catalogs, .agf), a model glass 'n_d/V_d' such as 1.5168/64.17, or AIR")
    return functools.partial(_catalogue_index, glass)


def _find_catalogue_glass(name: str):
    """The opticalglass object for a catalogue name ('N-BK7' or 'SCHOTT:N-BK7'), None if there is none."""
    if ":" in name:
        cat, glass = (x.strip() for x in name.split(":", 1))
        matches = [c for c in CATALOGUES if c.lower() == cat.lower()]
        if not matches:
            raise InputError(f"unknown glass catalogue '{cat}' in '{name}'", field="material",
                             valid=", ".join(CATALOGUES))
        search = [(matches[0], glass)]
    else:
        search = [(c, name.strip()) for c in CATALOGUES]
    for cat, glass in search:
        try:
            return _catalogue_glass(glass.upper(), cat)
        except Exception:
            continue
    return None


def _fused_silica(wl):
    l2 = np.asarray(wl, dtype=np.float64) ** 2
    return np.sqrt(1.0 + sum(b * l2 / (l2 - c) for b, c in zip(_MALITSON_B, _MALITSON_C)))


def successor(name: str) -> str | None:
    """The catalogue glass that replaced a legacy name: BK7 -> N-BK7 (lead-free), E-LAFH3 -> J-LAFH3,
    the catalogue glass of a moulding variant: L-TIM28_MOLD -> S-TIM28, and a glass melted again
    to a changed formula, which keeps its name with a letter added: N-PK52 -> N-PK52A.

    Uses opticalglass's name decoder: the same composition group, number and suffix
    with another prefix (N-, P-, S-, J-, ...) in one catalogue, N- ("new", the lead-free
    successor) preferred; failing that, the same name with the suffix A
    (Schott's and CDGM's mark of a reformulated glass). None when there is no such glass or it is
    ambiguous.
    """
    # lazy: keeps lensmount --help from loading opticalglass and pandas
    from opticalglass.glass import decode_glass_name

    name = re.sub(r"_MOLD(ED)?$", "", name.strip().upper())  # Zemax's moulded-variant names
    try:
        (group_num, prefix, suffix) = decode_glass_name(name)
    except Exception:
        return None
    if not group_num[0]:
        return None
    for cat in CATALOGUES:
        found = [g for g in _catalogue_names(cat) if "-" in g and g != name and _decoded(g) == (group_num, suffix)]
        new = [g for g in found if g.startswith("N-")]
        for pick in (new, found):
            if len(pick) == 1:
                return f"{cat.upper()}:{pick[0]}"
    if not suffix:
        for cat in CATALOGUES:
            if name + "A" in _catalogue_names(cat):
                return f"{cat.upper()}:{name}A"
    return None


def _decoded(glass: str):
    # lazy: keeps lensmount --help from loading opticalglass and pandas
    from opticalglass.glass import decode_glass_name

    try:
        group_num, _, suffix = decode_glass_name(glass)
    except Exception:
        return None
    return group_num, suffix


@functools.lru_cache(maxsize=None)
def _catalogue_names(catalogue: str) -> tuple[str, ...]:
    from opticalglass import glassfactory  # lazy: keeps lensmount --help from loading opticalglass and pandas

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return tuple(str(g).strip().upper() for g in glassfactory.get_glass_catalog(catalogue).get_glass_names())


def _catalogue_index(glass, wl):
    wl = np.asarray(wl, dtype=np.float64)
    # calc_rindex takes nm and accepts arrays (rindex() would look arrays up as line names).
    return np.asarray(glass.calc_rindex(wl * 1000.0), dtype=np.float64).reshape(wl.shape)


_T10 = "internal transmission mm, 10"


@functools.lru_cache(maxsize=None)
def _absorption(name: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(wavelengths µm, ascending; absorption coefficient 1/mm) from the catalogue's internal
    transmittance of a 10 mm sample; None where the material has no catalogue data."""
    import pandas as pd  # lazy: keeps lensmount --help from loading pandas

    if name.strip().upper() == AIR or MODEL_GLASS.match(name) or name.strip().upper() in _FUSED_SILICA_NAMES:
        return None
    medium(name)  # unknown names raise the usual InputError
    glass = _find_catalogue_glass(name)
    if glass is None:  # a user catalogue's glass, or one of the legacy table: no transmission data here
        return None
    t10 = pd.to_numeric(glass.glass_data()[_T10], errors="coerce")  # blank cells are no data, not 0
    t10 = t10[np.isfinite(t10.to_numpy(dtype=float))]
    if t10.empty:
        return None
    wl = t10.index.to_numpy(dtype=float) / 1000.0
    # T = 0 in the table is opaque to the table's precision: a finite, large absorption keeps it NaN-free
    alpha = -np.log(np.clip(t10.to_numpy(dtype=float), 1e-12, 1.0)) / 10.0
    order = np.argsort(wl)
    return wl[order], alpha[order]


def absorption_coefficient(material: str, wavelength_um) -> np.ndarray:
    """Bulk absorption coefficient a(λ) of `material`, 1/mm (the tracer's exp(-a L) per path).

    a = -ln(T10)/10 from the catalogue's internal transmittance of a 10 mm sample,
    interpolated linearly in wavelength and held at the end values outside the tabulated
    range. AIR, model glasses (n_d/V_d) and fused silica have no catalogue data: 0 (lossless).
    """
    wl = np.asarray(wavelength_um, dtype=np.float64)
    table = _absorption(material)
    return np.zeros(wl.shape) if table is None else np.interp(wl, *table)


def internal_transmittance(material: str, wavelength_um, path_mm) -> np.ndarray:
    """Bulk internal transmittance exp(-a(λ) L) of `path_mm` of `material` (Beer-Lambert), with
    a(λ) from `absorption_coefficient`. Arrays broadcast; negative paths count as 0. Never NaN.
    """
    path = np.maximum(np.asarray(path_mm, dtype=np.float64), 0.0)
    return np.exp(-absorption_coefficient(material, wavelength_um) * path)


def refractive_index(name: str, wavelength_um) -> np.ndarray:
    """n of material `name` at wavelength(s) in µm."""
    return np.asarray(medium(name)(wavelength_um), dtype=np.float64)
