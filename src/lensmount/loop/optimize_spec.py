"""The `[optimize]` table (DESIGN/optimize.toml): what `lensmount optimize` varies, minimises and respects.

    [optimize]
    trials = 12                      # candidates the search evaluates (the start is evaluated besides)

    [optimize.objective]
    kind = "stray_fraction"          # the scene's stray fraction
    scene = "case1-diaphragm-edge"   # a name under DESIGN/scenes or a file

    [optimize.variables]
    "hood.length_mm" = { low = 10.0, high = 30.0 }          # any numeric mount.toml key, dotted
    "vanes.count" = { low = 1, high = 4, integer = true }   # a whole number
    "vanes.finish" = { finishes = ["black-paint", "edge-lambert-10"] }  # a finish of finishes.toml

    [optimize.constraints]
    max_length_mm = 80.0             # overall length of the regenerated mount (z extent of its mesh)
    max_outer_diameter_mm = 40.0     # outer diameter of the regenerated mount

    [optimize.fidelity]
    photons_per_pass = 20_000
    passes = [4, 8]                  # every candidate gets the first; one within the noise of the best the next
    final_passes = 16                # the verdict's runs of the best and the start, on seeds the search never used

    [optimize.search]
    sampler_seed = 0                 # Optuna's TPE
    seed = 1                         # the simulation seed every candidate shares (common random numbers)

Every candidate also has to regenerate and pass the mount's checks; one that does not is
infeasible, and the report says why.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from lensmount.design.finishes import BUILTIN_FINISHES, load_finishes
from lensmount.errors import InputError
from lensmount.validation import input_error, parse_toml, read_text

SPEC_NAME = "optimize.toml"
VALID = "an [optimize] table with objective, variables and optionally constraints, fidelity, search (docs: " \
        "lensmount optimize --help)"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Variable(_Strict):
    """A numeric key between low and high (a whole number with integer = true), or a finish among `finishes`."""

    low: float | None = None
    high: float | None = None
    integer: bool = False
    finishes: tuple[str, ...] | None = None

    @model_validator(mode="after")
    def _one_kind(self):
        if self.finishes is not None:
            if self.low is not None or self.high is not None or self.integer or not self.finishes:
                raise ValueError("a finish variable takes only finishes = [two or more names]")
        elif self.low is None or self.high is None or not self.low < self.high:
            raise ValueError("a numeric variable needs low < high")
        elif self.integer and (self.low != int(self.low) or self.high != int(self.high)):
            raise ValueError("an integer variable needs whole-number bounds")
        return self


class Objective(_Strict):
    """What is minimised. One kind today; another (the PST over angles) is one more value of `kind`."""

    kind: Literal["stray_fraction"] = "stray_fraction"
    scene: str


class Constraints(_Strict):
    max_length_mm: float | None = Field(None, gt=0)
    max_outer_diameter_mm: float | None = Field(None, gt=0)


class Fidelity(_Strict):
    photons_per_pass: int | None = Field(None, ge=1)  # None: the scene's [run] photons
    passes: tuple[int, ...] = Field((4, 8), min_length=1)
    final_passes: int = Field(16, ge=3)

    @model_validator(mode="after")
    def _rising(self):
        if self.passes[0] < 3 or any(b <= a for a, b in zip(self.passes, self.passes[1:])):
            raise ValueError("passes must rise, the first at least 3 (an error bar needs 3 passes)")
        return self


class Search(_Strict):
    sampler_seed: int = Field(0, ge=0)
    seed: int = Field(1, ge=0)
    confidence: float = Field(0.99, gt=0.5, lt=1.0)


class OptimizeSpec(_Strict):
    trials: int = Field(12, ge=1)
    objective: Objective
    variables: dict[str, Variable] = Field(min_length=1)
    constraints: Constraints = Constraints()
    fidelity: Fidelity = Fidelity()
    search: Search = Search()


class _File(_Strict):
    optimize: OptimizeSpec


def load_optimize(design: Path, path: Path | None = None) -> OptimizeSpec:
    """DESIGN/optimize.toml (or `path`) validated; finish names checked against the design's finishes."""
    path = Path(path) if path is not None else Path(design) / SPEC_NAME
    text = read_text(path, "the optimize table", VALID)
    doc = parse_toml(text, str(path), VALID)
    try:
        spec = _File.model_validate(doc).optimize
    except ValidationError as exc:
        raise input_error(exc, _File, file=str(path), text=text, valid=VALID) from None
    known = set(BUILTIN_FINISHES) | set(load_finishes(design).finishes)
    for key, var in spec.variables.items():
        if not all(key.split(".")):
            raise InputError(f"variable '{key}' is not a dotted mount.toml key", file=str(path),
                             field=f"optimize.variables.{key}", valid="TABLE.KEY, e.g. hood.length_mm")
        unknown = sorted(set(var.finishes or ()) - known)
        if unknown:
            raise InputError(f"unknown finish {', '.join(map(repr, unknown))}", file=str(path),
                             field=f"optimize.variables.{key}.finishes",
                             valid="finishes the design's finishes.toml defines or built-ins: "
                                   + ", ".join(sorted(known)))
    return spec


__all__ = ["SPEC_NAME", "Constraints", "Fidelity", "Objective", "OptimizeSpec", "Search", "Variable", "load_optimize"]
