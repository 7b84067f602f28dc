"""`lensmount simulate DESIGN --scene SCENE`: regenerate (cached) → scene → passes → results.

Parses, calls, prints — the physics lives in lensmount.integrators, the loop in
lensmount.runner, the files in lensmount.results.
"""

from __future__ import annotations

import hashlib
import math
import signal
from pathlib import Path
from typing import Optional

import typer

from lensmount.cli import app
from lensmount.errors import InputError

METHODS = ("bidirectional", "forward")


def _load_prescription(design_dir: Path):
    """The lens of a design folder (through design.folder when present, else design.lens)."""
    try:
        from lensmount.design.folder import load_design
    except ImportError:
        load_design = None
    if load_design is not None:
        design = load_design(design_dir)
        for name in ("prescription", "lens"):
            if hasattr(design, name):
                return getattr(design, name)
    from lensmount.design.lens import load_lens

    for name in ("lens.toml", "lens.zmx"):
        if (design_dir / name).exists():
            return load_lens(design_dir / name)
    raise InputError("no lens file in the design folder", file=str(design_dir), valid="lens.toml or lens.zmx")


def _load_mesh(design_dir: Path, cache_dir: Path):
    """The mount's tagged mesh, regenerated only when the design changed (cad.regenerate caches)."""
    from lensmount.cad import regenerate
    from lensmount.cad.mesh import TaggedMesh

    manifest = regenerate(design_dir, cache_dir)
    return TaggedMesh.load(Path(cache_dir) / getattr(manifest, "mesh", "mesh.npz"))


def input_hash(design_dir: Path, scene_path: Path, **params) -> str:
    """sha256 over the design files, the scene file and the run parameters that change results."""
    h = hashlib.sha256()
    files = sorted(p for p in design_dir.iterdir() if p.is_file() and p.suffix in (".toml", ".zmx", ".json"))
    for p in files + [scene_path]:
        h.update(p.name.encode())
        h.update(p.read_bytes())
    for k in sorted(params):
        h.update(f"{k}={params[k]!r}".encode())
    return h.hexdigest()[:16]


@app.command()
def simulate(
    design: Path = typer.Argument(..., help="Design folder (lens.toml or lens.zmx, mount.toml, scenes/)."),
    scene: Path = typer.Option(..., "--scene", help="Scene file (scenes/*.toml)."),
    method: str = typer.Option("bidirectional", "--method", help="bidirectional | forward"),
    seed: Optional[int] = typer.Option(None, "--seed", min=0, help="Run seed, >= 0 (default: the scene's [run] seed)."),
    out: Optional[Path] = typer.Option(None, "--out", help="Output folder (default out/<scene name>)."),
    photons: Optional[int] = typer.Option(None, "--photons", help="Stop after this many photons in total."),
    time_s: Optional[float] = typer.Option(None, "--time", help="Stop after this many seconds."),
    target_rel_error: Optional[float] = typer.Option(None, "--target-rel-error",
                                                     help="Stop when the total stray flux has this relative error."),
    passes: Optional[int] = typer.Option(None, "--passes", help="At most this many passes."),
    photons_per_pass: Optional[int] = typer.Option(None, "--photons-per-pass",
                                                   help="Photons per pass (default: the scene's [run] photons)."),
    samples_per_pixel: int = typer.Option(1, "--samples-per-pixel", help="Backward samples per pixel per pass."),
    alpha: float = typer.Option(0.7, "--alpha", help="Radius shrink parameter, 0 < alpha < 1."),
    workers: int = typer.Option(0, "--workers", help="Worker processes (0 = one per core)."),
    resume: bool = typer.Option(False, "--resume", help="Continue from DIR/checkpoint.npz."),
) -> None:
    """Simulate the stray light on the detector and write irradiance.exr, preview.png, summary.json."""
    from lensmount.cli import fail

    try:
        _simulate(design, scene, method, seed, out, photons, time_s, target_rel_error, passes, photons_per_pass,
                  samples_per_pixel, alpha, workers, resume)
    except InputError as error:
        fail(error)


def _simulate(design, scene, method, seed, out, photons, time_s, target_rel_error, passes, photons_per_pass,
              samples_per_pixel, alpha, workers, resume) -> None:
    from lensmount.analysis.metrics import aperture_flux_normalised
    from lensmount.analysis.passes import Accumulator
    from lensmount.analysis.summary import build_summary
    from lensmount.design.scene import load_scene
    from lensmount.integrators.bidirectional import part_names
    from lensmount.results import write_run
    from lensmount.runner import PassJob, Runner, Stopping, default_workers
    from lensmount.scene.build import build_scene

    if method not in METHODS:
        raise InputError(f"unknown method '{method}'", field="--method", valid=" | ".join(METHODS))
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha = {alpha:g} is out of range", field="--alpha", valid="0 < alpha < 1")
    for name, value in (("--photons", photons), ("--passes", passes), ("--photons-per-pass", photons_per_pass)):
        if value is not None and value < 1:
            raise InputError(f"{name} must be at least 1, got {value}", field=name, valid="a positive integer")
    if target_rel_error is not None and not target_rel_error > 0:
        raise InputError("the target relative error must be positive", field="--target-rel-error",
                         valid="a number > 0, e.g. 0.05")
    if samples_per_pixel < 1:
        raise InputError("need at least one sample per pixel", field="--samples-per-pixel", valid="an integer ≥ 1")
    design = Path(design)
    if not design.is_dir():
        raise InputError("design folder not found", file=str(design), valid="a folder with lens.toml and mount.toml")

    out = Path(out) if out is not None else Path("out") / Path(scene).stem
    checkpoint = out / "checkpoint.npz"
    if resume and not checkpoint.exists():
        raise InputError("no checkpoint to resume from", file=str(checkpoint), valid="run once without --resume")
    spec = load_scene(scene)
    seed = spec.run.seed if seed is None else seed
    per_pass = photons_per_pass or spec.run.photons
    prescription = _load_prescription(design)
    mesh = _load_mesh(design, out / "geometry")
    sc = build_scene(prescription, mesh, spec)

    if not any(v is not None for v in (photons, time_s, target_rel_error, passes)):
        target_rel_error = spec.run.target_rel_error
        passes = spec.run.passes if target_rel_error is None else None
    stopping = Stopping(photons=photons, time_s=time_s, target_rel_error=target_rel_error,
                        max_passes=passes or 10_000)

    options = {"samples_per_pixel": samples_per_pixel} if method == "bidirectional" else {}
    digest = input_hash(design, Path(scene), method=method, photons_per_pass=per_pass, alpha=alpha, **options)
    names = part_names(sc) if method == "bidirectional" else None
    acc = None
    if resume:
        acc, meta = Accumulator.load(checkpoint)
        if meta.get("input_hash") != digest or int(meta.get("seed", -1)) != seed or meta.get("method") != method:
            raise InputError("the checkpoint belongs to another run (inputs, seed or method differ)",
                             file=str(checkpoint), valid=f"the same design, scene, method and --seed {seed}")
    if acc is None:
        if names is None:  # the forward estimator names its own channels: take them from one tiny pass
            names = _forward_part_names(sc)
        acc = Accumulator.empty((sc.detector.ny, sc.detector.nx), names, sc.detector.pixel_area)

    def job(i: int) -> PassJob:
        return PassJob(method, per_pass, seed, i, alpha, options)

    effects = {k: bool(getattr(sc.effects, k)) for k in ("scatter", "ghosts", "direct")}
    direction = getattr(sc.source, "off_axis_deg", 0.0)
    aperture = aperture_flux_normalised(2.0 * math.sqrt(sc.entrance_pupil_area_mm2 / math.pi),
                                        math.radians(direction))
    n_workers = workers or default_workers()

    def summary_now(runner_elapsed: float) -> dict:
        return build_summary(acc, method=method, seed=seed, effects_ran=[k for k, v in effects.items() if v],
                             effects_skipped=[k for k, v in effects.items() if not v], time_s=runner_elapsed,
                             aperture_flux_mm2=aperture, input_hash=digest,
                             extra={"photons_per_pass": per_pass, "alpha": alpha, "workers": n_workers,
                                    "scene": str(scene), "design": str(design)})

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    total = stopping.max_passes if (photons is None and time_s is None and target_rel_error is None) else None
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                  TimeElapsedColumn(), transient=False) as bar:
        task = bar.add_task(method, total=total, info="")

        def progress(a, elapsed):
            rel = a.rel_error()
            err = f"{100 * rel:.2f} %" if math.isfinite(rel) else "—"
            bar.update(task, completed=a.n, info=f"passes {a.n} · photons {a.photons:,} · rel. error {err}")

        runner = Runner(sc, job, acc, workers=n_workers, checkpoint=checkpoint,
                        checkpoint_meta={"seed": seed, "input_hash": digest, "method": method},
                        progress=progress)
        previous = signal.getsignal(signal.SIGINT)
        try:
            runner.run(stopping)
        finally:
            signal.signal(signal.SIGINT, previous)

    det = sc.detector
    field_r = _field_radius(prescription)
    paths = write_run(out, acc, summary_now(runner.elapsed),
                      extent_mm=(-det.width / 2, det.width / 2, -det.height / 2, det.height / 2),
                      field_radius_mm=field_r)
    print_summary(summary_now(runner.elapsed), paths)
    if runner.interrupted:
        typer.echo("interrupted: results and checkpoint written; continue with --resume", err=True)
        raise typer.Exit(code=130)


def print_summary(summary: dict, paths: dict) -> None:
    """The figures an engineer reads first: the stray level with its error bar, then who carries it."""
    from rich.console import Console
    from rich.table import Table

    def pm(value, error):
        return f"{value:.4g} ± {error:.2g}" if error is not None else f"{value:.4g}"

    console = Console()
    table = Table(title=f"{summary['method']} · {summary['passes']} passes · {summary['photons']:,} photons "
                        f"· {summary['time_s']:.1f} s", title_justify="left", show_header=False)
    table.add_column(style="bold")
    table.add_column(justify="right")
    table.add_row("stray fraction", pm(summary["stray_fraction"], summary.get("stray_fraction_std_error")))
    rel = summary.get("stray_fraction_rel_error")
    table.add_row("relative error", f"{100 * rel:.2f} %" if rel is not None else "—")
    drift = summary.get("stray_fraction_drift")
    if drift is not None:
        p = summary.get("stray_fraction_drift_p")
        table.add_row("radius drift (2nd half vs 1st)", f"{100 * drift:+.1f} %" + (f" (p = {p:.2f})" if p is not None else ""))
    table.add_row("peak irradiance / E_sun", f"{summary['peak_irradiance']:.4g}")
    table.add_row("effects", ", ".join(summary["effects"]) + (f" (skipped: {', '.join(summary['effects_skipped'])})"
                                                               if summary["effects_skipped"] else ""))
    if summary.get("lost_flux"):
        table.add_row("lost flux (mm²)", f"{summary['lost_flux']:.3g}")
    console.print(table)
    parts = sorted(((v["fraction"], name, v["std_error"]) for name, v in summary["per_part"].items()
                    if v["fraction"] > 0), reverse=True)
    if parts:
        by_part = Table(title="stray fraction by part (last scattering surface)", title_justify="left")
        by_part.add_column("part")
        by_part.add_column("fraction", justify="right")
        by_part.add_column("share", justify="right")
        total = sum(f for f, _, _ in parts)
        for fraction, name, error in parts[:10]:
            by_part.add_row(name, pm(fraction, error), f"{100 * fraction / total:.1f} %")
        if len(parts) > 10:
            by_part.add_row(f"… {len(parts) - 10} more", "", "")
        console.print(by_part)
    console.print("wrote " + ", ".join(str(p) for p in paths.values()))


def _forward_part_names(sc) -> list[str]:
    from lensmount.runner import _resolve, PASS_FUNCTIONS, TRACER

    est = _resolve(PASS_FUNCTIONS["forward"])(sc, _resolve(TRACER)(sc), 1, 0, 0)
    return list(est.part_names)


def _field_radius(prescription) -> float | None:
    """Image height of the full field, efl · tan(max field), for the preview outline."""
    try:
        from lensmount.optics.paraxial import paraxial

        return abs(paraxial(prescription).efl) * math.tan(math.radians(prescription.max_field_deg)) or None
    except Exception:
        return None
