"""`sweep`: regenerate and simulate every combination of design and scene parameters, then rank.

    sweep(SweepOptions(design, scene, params=[Param.parse("mount.hood.length_mm=80,100,120"),
                                               Param.parse("mount.vanes.aperture_margin_mm=0.2,0.5")]))

A parameter names a file (`mount`, `lens` for lens.toml, `finishes` for the design's
finishes.toml, `scene`), a table path and a key; its values are TOML literals
(`finishes.finishes.black-paint.reflectance=0.02,0.05`). Each variant is a copy of the design folder (and of
the scene) with those keys set, written under OUT/variants/NN/, regenerated and
simulated with the same seed and stopping rules through `loop.simulate`, so its passes
run on whatever executor the simulate options name (local processes or Dask). A mount
parameter whose values lay out the same parts (the same templates and finishes) is refused
before anything is simulated: it would only measure noise. Variants
whose stray levels differ by less than the noise are ties: ranks are given to groups,
and a group holds every variant not separated from its best member at the chosen
confidence.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import shutil
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import tomli_w

from lensmount.atomic import atomic_path, write_text
from lensmount.design.folder import load_design
from lensmount.errors import InputError
from lensmount.loop.simulate import Observer, SimulateOptions, simulate

FILES = {"mount": "mount.toml", "lens": "lens.toml", "finishes": "finishes.toml", "scene": None}


@dataclass(frozen=True)
class Param:
    """One swept key: file ('mount' | 'lens' | 'finishes' | 'scene'), table path and key, and its values."""

    file: str
    keys: tuple[str, ...]
    values: tuple

    @property
    def name(self) -> str:
        return ".".join((self.file,) + self.keys)

    @classmethod
    def parse(cls, text: str) -> "Param":
        """'mount.vanes.count=3,5,7' → Param('mount', ('vanes', 'count'), (3, 5, 7))."""
        path, eq, values = text.partition("=")
        parts = tuple(p.strip() for p in path.strip().split("."))
        if not eq or len(parts) < 2 or parts[0] not in FILES or not all(parts) or not values.strip():
            raise InputError(f"parameter '{text}' is not understood", field="--param",
                             valid="FILE.TABLE.KEY=V1,V2,... with FILE one of mount, lens, finishes, scene, "
                                   "e.g. mount.hood.length_mm=80,100,120")
        return cls(parts[0], parts[1:], tuple(_literal(v.strip()) for v in values.split(",")))


def _literal(text: str):
    """A TOML literal (3, 0.5, true, "black-anodised"); a bare word is taken as a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


@dataclass(frozen=True)
class SweepOptions:
    """design, scene : the base design folder and scene file; params : what varies;
    simulate : the simulate options every variant shares (design, scene and out are set per variant);
    out : where variants, table and plot go; confidence : for telling variants apart."""

    design: Path
    scene: Path
    params: tuple[Param, ...]
    out: Path = Path("out/sweep")
    simulate: SimulateOptions | None = None
    confidence: float = 0.95


@dataclass
class Variant:
    index: int
    values: dict
    stray_fraction: float | None = None
    std_error: float | None = None
    bias_bound: float = 0.0
    bias_unbounded: str | None = None  # why the run could not bound its kernel bias (`analysis.bias`)
    rank: int = 0
    tied_with: list[int] = field(default_factory=list)
    out: Path | None = None


@dataclass
class SweepResult:
    variants: list[Variant]
    table: Path
    plot: Path | None


def variants_of(params: tuple[Param, ...]) -> list[dict]:
    """Every combination, in the order the parameters and their values were given."""
    names = [p.name for p in params]
    return [dict(zip(names, combo)) for combo in itertools.product(*(p.values for p in params))]


def sweep(options: SweepOptions, observer: Observer | None = None) -> SweepResult:
    """Build, simulate and rank every variant (see the module docstring)."""
    if not options.params:
        raise InputError("nothing to sweep", field="--param", valid="at least one --param FILE.TABLE.KEY=V1,V2")
    if not 0.5 <= options.confidence < 1.0:
        raise InputError(f"confidence {options.confidence:g} is out of range", field="--confidence",
                         valid="a number in [0.5, 1), e.g. 0.95")
    obs = observer or Observer()
    base = options.simulate or SimulateOptions(options.design, options.scene)
    grid = variants_of(options.params)
    written = [write_variant(Path(options.design), Path(options.scene), Path(options.out) / "variants" / f"{k:02d}",
                              options.params, values) for k, values in enumerate(grid)]
    refuse_identical_layouts(options.params, grid, [design for design, _ in written])
    variants = []
    for k, (values, (design, scene)) in enumerate(zip(grid, written)):
        folder = Path(options.out) / "variants" / f"{k:02d}"
        obs.stage(f"variant {k + 1}: " + ", ".join(f"{n} = {v}" for n, v in values.items()))
        run = simulate(replace(base, design=design, scene=scene, out=folder / "run", geometry=folder / "build",
                               store=base.store, resume=False), obs)
        run.raise_if_stopped("the sweep stopped at this variant: run the same sweep again")
        s = run.summary
        variants.append(Variant(k, values, s.get("stray_fraction"), s.get("stray_fraction_std_error"),
                                s.get("stray_fraction_bias_bound") or 0.0, s.get("stray_fraction_bias_unbounded"),
                                out=run.out))
    rank(variants, options.confidence)
    table = Path(options.out) / "sweep.csv"
    write_text(table, _csv(variants, options.params))
    plot = _plot(variants, options.params, Path(options.out) / "sweep.png")
    return SweepResult(variants, table, plot)


def write_variant(design: Path, scene: Path, folder: Path, params, values: dict) -> tuple[Path, Path]:
    """A copy of the design folder and the scene with the variant's keys set."""
    target = folder / "design"
    if target.exists():
        shutil.rmtree(target)
    shutil.copytree(design, target, ignore=shutil.ignore_patterns("build", "out", ".lensmount", ".git"))
    scene_copy = folder / scene.name
    shutil.copy2(scene, scene_copy)
    for p in params:
        path = scene_copy if p.file == "scene" else target / FILES[p.file]
        if not path.exists() and p.file != "finishes":  # no finishes.toml yet: the swept key starts one
            raise InputError(f"the design has no {path.name} to set '{p.name}' in", file=str(path), field="--param",
                             valid="a parameter of a file the design has (a .zmx lens cannot be swept)")
        doc = tomllib.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
        table = doc
        for key in p.keys[:-1]:
            table = table.setdefault(key, {})
            if not isinstance(table, dict):
                raise InputError(f"'{key}' is not a table", file=str(path), field=p.name, valid="TABLE.KEY")
        table[p.keys[-1]] = values[p.name]
        write_text(path, tomli_w.dumps(doc))  # the loaders validate it: an unknown key is an error there
    return target, scene_copy


def refuse_identical_layouts(params, grid: list[dict], designs: list[Path]) -> None:
    """InputError naming a mount parameter two of whose values lay out the same parts (templates,
    sizes, finishes) with everything else equal: those variants differ only by noise."""
    from lensmount.cad.layout import plan  # lazy: keeps lensmount --help from loading cad and matplotlib

    layouts: dict[int, str] = {}

    def layout(k: int) -> str:
        if k not in layouts:
            design = load_design(designs[k])
            layouts[k] = repr(plan(design.prescription, design.mount).parts)
        return layouts[k]

    for p in params:
        if p.file != "mount":
            continue
        for i, a in enumerate(grid):
            for j in range(i + 1, len(grid)):
                b = grid[j]
                if a[p.name] != b[p.name] and all(a[n] == b[n] for n in a if n != p.name) and layout(i) == layout(j):
                    raise InputError(f"{p.name} = {a[p.name]!r} and {b[p.name]!r} lay out the same mount (the same "
                                     "parts, sizes and finishes): the sweep would only measure noise",
                                     field="--param", valid="a key that changes the mount for these values "
                                     "(under [vanes] placement = \"line-of-sight\" the construction sets the hood "
                                     "vanes; count applies to placement = \"even\")")


def rank(variants: list[Variant], confidence: float) -> None:
    """Rank by stray fraction, lowest first; a variant within the noise of a group's best joins its group.

    Two variants differ when |a − b| exceeds z·√(σa² + σb²) plus both bias bounds, z the
    two-sided normal quantile at `confidence`. Unknown values rank last.
    """
    from scipy.stats import norm  # lazy: keeps lensmount --help from loading scipy.stats

    z = float(norm.ppf(0.5 + confidence / 2))
    known = sorted((v for v in variants if v.stray_fraction is not None), key=lambda v: v.stray_fraction)
    group_best, r = None, 0
    for v in known:
        if group_best is None or not _same(group_best, v, z):
            group_best, r = v, r + 1
        v.rank = r
    for v in variants:
        if v.stray_fraction is None:
            v.rank = r + 1
        v.tied_with = [w.index for w in known if w is not v and w.rank == v.rank]


def _same(a: Variant, b: Variant, z: float) -> bool:
    sa, sb = a.std_error, b.std_error
    if sa is None or sb is None or a.bias_unbounded or b.bias_unbounded:
        return True  # no error bar, or a bias it cannot bound: nothing can be told apart
    return abs(a.stray_fraction - b.stray_fraction) <= z * math.hypot(sa, sb) + a.bias_bound + b.bias_bound


NO_ERROR_BAR = "no error bar: fewer than 3 passes"  # why std_error is blank (analysis.error_bar.MIN_PASSES)


def _csv(variants: list[Variant], params) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(["variant", *(p.name for p in params), "stray_fraction", "std_error", "bias_bound", "rank",
                "tied_with", "results", "note"])
    for v in variants:
        note = NO_ERROR_BAR if v.stray_fraction is not None and v.std_error is None else ""
        note = f"cannot bound its kernel bias: {v.bias_unbounded}" if v.bias_unbounded else note
        w.writerow([v.index, *(v.values[p.name] for p in params), _num(v.stray_fraction), _num(v.std_error),
                    _num(v.bias_bound), v.rank, " ".join(map(str, v.tied_with)), str(v.out), note])
    return buf.getvalue()


def _num(x) -> str:
    return "" if x is None else f"{x:.6g}"


def _plot(variants: list[Variant], params, path: Path) -> Path | None:
    """sweep.png (`figure`)."""
    import matplotlib.pyplot as plt  # lazy: keeps lensmount --help from loading matplotlib

    fig = figure(variants, params)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        fig.savefig(fh, format="png", dpi=110)
    plt.close(fig)
    return path


def figure(variants: list[Variant], params):
    """Stray fraction with ±2σ bars against the first parameter, one line per combination of the others.

    Honest at a glance: the axis starts at 0 (a 0.002 % difference is no steep drop), the scale
    sits in the axis label (no offset text over the title), a parameter of whole numbers gets whole
    ticks, and variants without an error bar say so on the plot."""
    import matplotlib  # lazy: keeps lensmount --help from loading matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    first, rest = params[0], params[1:]
    known = [v for v in variants if v.stray_fraction is not None]
    top = max((v.stray_fraction + 2 * (v.std_error or 0) + v.bias_bound for v in known), default=0.0)
    exponent = math.floor(math.log10(top)) if top > 0 else 0
    unit = 10.0 ** exponent
    fig, ax = plt.subplots(figsize=(7, 4.5))
    numeric = all(_is_number(v.values[first.name]) for v in variants)
    for combo in itertools.product(*(p.values for p in rest)) if rest else [()]:
        group = [v for v in known if all(v.values[p.name] == c for p, c in zip(rest, combo))]
        if not group:
            continue
        x = [v.values[first.name] for v in group] if numeric else [first.values.index(v.values[first.name])
                                                                   for v in group]
        label = ", ".join(f"{p.name} = {c}" for p, c in zip(rest, combo)) or None
        ax.errorbar(x, [v.stray_fraction / unit for v in group], yerr=[2 * (v.std_error or 0) / unit for v in group],
                    marker="o", capsize=3, label=label)
        for xi, v in zip(x, group):
            ax.annotate(f"#{v.rank}", (xi, v.stray_fraction / unit), textcoords="offset points", xytext=(4, 4),
                        fontsize=8)
    if not numeric:
        ax.set_xticks(range(len(first.values)), [str(v) for v in first.values])
    elif all(isinstance(v, int) for v in first.values):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # 3, 4, 5 vanes, not 3.5
    ax.ticklabel_format(axis="both" if numeric else "y", useOffset=False, style="plain")
    ax.set_ylim(0, 1.1 * top / unit if top > 0 else 1.0)
    ax.set_xlabel(first.name)
    scale = f" (×10^{exponent})" if exponent else ""
    ax.set_ylabel(f"stray fraction{scale}, bars ±2σ")
    ax.set_title("sweep: equal ranks are ties (within the noise)")
    missing = sum(v.std_error is None for v in known)
    if missing:
        ax.text(0.01, 0.02, f"{missing} variant(s) without a bar: {NO_ERROR_BAR}", transform=ax.transAxes,
                fontsize=8, color="0.3")
    if rest:
        ax.legend(fontsize=8)
    fig.tight_layout()
    return fig


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


__all__ = ["Param", "SweepOptions", "SweepResult", "Variant", "sweep", "rank", "refuse_identical_layouts", "write_variant",
           "variants_of"]
