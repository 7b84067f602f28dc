"""Zemax glass catalogues (.agf): the format glass vendors publish and engineers already keep.

What a catalogue holds and how it is read (one glass per NM line, its data on the lines after it):
    NM name formula MIL n_d V_d exclude status ...   formula: Zemax's dispersion formula number
    CD c1 c2 ...                                      the formula's coefficients (λ in µm)
    LD λmin λmax                                      the range the coefficients hold for, µm
Other lines (thermal data ED/TD, transmission IT, comments) do not change the index at 20 °C
in air and are skipped. Files are UTF-16 (with a BOM, as Zemax writes them), UTF-8 or Latin-1.

Dispersion formulas (Zemax's numbering; λ in µm; the formulas of the Zemax manual):
    1 Schott       n² = a0 + a1 λ² + a2 λ⁻² + a3 λ⁻⁴ + a4 λ⁻⁶ + a5 λ⁻⁸
    2 Sellmeier 1  n² − 1 = Σ(k=1..3) K_k λ² / (λ² − L_k)        CD K1 L1 K2 L2 K3 L3
    3 Herzberger   n = A + B L + C L² + D λ² + E λ⁴ + F λ⁶, L = 1 / (λ² − 0.028)
    5 Conrady      n = n0 + A / λ + B / λ^3.5
    6 Sellmeier 3  as Sellmeier 1 with four terms
    9 Sellmeier 4  n² = A + B λ² / (λ² − C) + D λ² / (λ² − E)
   10 Extended     n² = a0 + a1 λ² + a2 λ⁻² + a3 λ⁻⁴ + a4 λ⁻⁶ + a5 λ⁻⁸ + a6 λ⁻¹⁰ + a7 λ⁻¹²
   11 Sellmeier 5  as Sellmeier 1 with five terms
   12 Extended 2   n² = a0 + a1 λ² + a2 λ⁻² + a3 λ⁻⁴ + a4 λ⁻⁶ + a5 λ⁻⁸ + a6 λ⁴ + a7 λ⁶
Other formulas are an error naming the glass and the line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lensmount.errors import InputError
from lensmount.optics.glass import add_catalogue
from lensmount.optics.io.zemax_file import read_text

FORMULAS = {1: "Schott", 2: "Sellmeier 1", 3: "Herzberger", 5: "Conrady", 6: "Sellmeier 3", 9: "Sellmeier 4",
            10: "Extended", 11: "Sellmeier 5", 12: "Extended 2"}
_SELLMEIER_TERMS = {2: 3, 6: 4, 11: 5}


@dataclass(frozen=True)
class AgfGlass:
    name: str
    formula: int
    coefficients: tuple[float, ...]
    nd: float
    vd: float
    line: int
    wavelength_range_um: tuple[float, float] | None = None

    def index(self, wavelength_um) -> np.ndarray:
        """n at wavelength(s) in µm by the glass's dispersion formula."""
        lam = np.asarray(wavelength_um, dtype=np.float64)
        c = np.zeros(10)
        c[: len(self.coefficients)] = self.coefficients[:10]
        l2 = lam * lam
        f = self.formula
        if f in _SELLMEIER_TERMS:
            k, ll = c[0:2 * _SELLMEIER_TERMS[f]:2], c[1:2 * _SELLMEIER_TERMS[f]:2]
            return np.sqrt(1.0 + sum(kk * l2 / (l2 - li) for kk, li in zip(k, ll)))
        if f == 1:
            return np.sqrt(c[0] + c[1] * l2 + c[2] / l2 + c[3] / l2**2 + c[4] / l2**3 + c[5] / l2**4)
        if f == 3:
            big_l = 1.0 / (l2 - 0.028)
            return c[0] + c[1] * big_l + c[2] * big_l**2 + c[3] * l2 + c[4] * l2**2 + c[5] * l2**3
        if f == 5:
            return c[0] + c[1] / lam + c[2] / lam**3.5
        if f == 9:
            return np.sqrt(c[0] + c[1] * l2 / (l2 - c[2]) + c[3] * l2 / (l2 - c[4]))
        if f == 10:
            return np.sqrt(c[0] + c[1] * l2 + sum(c[k] / l2 ** (k - 1) for k in range(2, 8)))
        # 12, Extended 2 (read_agf admits no other)
        return np.sqrt(c[0] + c[1] * l2 + sum(c[k] / l2 ** (k - 1) for k in range(2, 6))
                       + c[6] * l2**2 + c[7] * l2**3)


def read_agf(path) -> dict[str, AgfGlass]:
    """The glasses of an .agf file by upper-case name."""
    path = Path(path)
    return parse_agf(read_text(path), str(path))


def register_catalogue(path) -> str:
    """Read a user glass catalogue (.agf) and make its glasses known by name (`optics.glass.add_catalogue`);
    returns the catalogue's name, by which `NAME:GLASS` selects one of them. The same file again is
    read again (it may have changed)."""
    path = Path(path).resolve()
    return add_catalogue(path, read_agf(path))


def parse_agf(text: str, file: str = "catalogue.agf") -> dict[str, AgfGlass]:
    glasses: dict[str, AgfGlass] = {}
    current: dict | None = None

    def finish():
        if current is not None:
            glass = AgfGlass(**current)
            glasses[glass.name.upper()] = glass

    for ln, raw in enumerate(text.splitlines(), start=1):
        parts = raw.split()
        if not parts:
            continue
        cmd, args = parts[0].upper(), parts[1:]
        if cmd == "NM":
            finish()
            if len(args) < 5:
                raise InputError("an NM line needs the name, formula, MIL code, n_d and V_d", file=file, line=ln,
                                 valid="NM name formula MIL n_d V_d ... (Zemax's .agf format)")
            formula = _number(args[1], file, ln, "formula")
            if formula not in FORMULAS:
                raise InputError(f"glass {args[0]} uses dispersion formula {formula:g}, which lensmount does not "
                                 "evaluate", file=file, line=ln,
                                 valid="formula " + ", ".join(f"{k} ({v})" for k, v in FORMULAS.items()))
            current = dict(name=args[0], formula=int(formula), coefficients=(), nd=_number(args[3], file, ln, "n_d"),
                           vd=_number(args[4], file, ln, "V_d"), line=ln)
        elif cmd == "CD" and current is not None:
            current["coefficients"] = tuple(_number(a, file, ln, "coefficient") for a in args)
        elif cmd == "LD" and current is not None and len(args) >= 2:
            current["wavelength_range_um"] = (_number(args[0], file, ln, "wavelength"),
                                              _number(args[1], file, ln, "wavelength"))
    finish()
    if not glasses:
        raise InputError("no glass (NM line) in the catalogue", file=file, valid="a Zemax .agf glass catalogue")
    return glasses


def _number(token: str, file: str, line: int, what: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise InputError(f"{what} '{token}' is not a number", file=file, line=line, valid="a decimal number") from None
    if not math.isfinite(value):
        raise InputError(f"{what} '{token}' is not a finite number", file=file, line=line, valid="a decimal number")
    return value


__all__ = ["AgfGlass", "FORMULAS", "parse_agf", "read_agf", "register_catalogue"]
