"""Paths down to the CAD face: the paper's case 2 on the reference design.

One small bidirectional run through `loop.simulate` (detector 60 × 60, 4 passes of 60 000
photons), then `lensmount paths RESULT --faces`. The checks compare two independent
accountings of the same light: the film's per-part channels (the part of the last scattering
vertex, summed per pixel) against the paths grouped by their last event; and the faces the
critical ∩ illuminated ranking puts first (view map × photons, no detector deposit involved)
against the faces whose scatter sends most flux to the detector.
"""

import shutil
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.analysis.paths import read_paths
from lensmount.mesh import ROLES
from lensmount.cli import app
from lensmount.integrators.paths import EMPTY
from lensmount.loop.simulate import SimulateOptions, simulate

pytestmark = pytest.mark.slow
DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    design = tmp_path_factory.mktemp("design") / "double-gauss-360"
    shutil.copytree(DESIGN, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    scene = design / "scenes" / "case2-lambertian.toml"
    scene.write_text(scene.read_text().replace("pixels = [600, 600]", "pixels = [60, 60]"))
    out = design.parent / "out"
    result = simulate(SimulateOptions(design=design, scene=scene, method="bidirectional", out=out, passes=4,
                                      photons_per_pass=60_000, workers=1, record=False))
    return result.summary, out


def test_top_paths_name_parts_and_faces_in_order_and_sum_to_the_total(run):
    summary, out = run
    top = summary["top_paths"]
    assert len(top["paths"]) == 10 and top["distinct_paths"] > 10
    for row in top["paths"]:
        assert row["events"], row
        for e in row["events"]:
            assert e["role"] in ROLES and isinstance(e["face"], int) and e["part"] in summary["per_part"]
    # the listed paths and the rest add up to the stray fraction (one accounting)...
    listed = sum(r["fraction"] for r in top["paths"]) + top["other"]["fraction"]
    assert listed == pytest.approx(summary["stray_fraction"], rel=1e-9)
    # ...and the top 10 alone lie within the error of the total: the rest is small against it
    gap = summary["stray_fraction"] - sum(r["fraction"] for r in top["paths"])
    assert 0 <= gap <= 2 * summary["stray_fraction_std_error"], (gap, summary["stray_fraction_std_error"])
    # the paths grouped by their last event's part are the film's per-part channels (the other accounting)
    sums, tags, _, aperture, _ = read_paths(out / "paths.npz")
    by_part = defaultdict(float)
    for sig, flux in zip(sums.signature.tolist(), sums.mean_flux()):
        if sig != EMPTY:
            by_part[tags[sums.events[sig][-1]].part] += flux / aperture
    for part, row in summary["per_part"].items():
        assert by_part.get(part, 0.0) == pytest.approx(row["fraction"], rel=1e-6, abs=1e-15), part
    print("top paths:", [(" → ".join(e["name"] for e in r["events"]), r["fraction"], r["std_error"])
                         for r in top["paths"][:4]])


def test_critical_and_illuminated_puts_the_faces_that_send_most_stray_flux_first(run):
    summary, out = run
    sums, tags, _, aperture, _ = read_paths(out / "paths.npz")
    by_face = defaultdict(float)  # stray flux by the face that scattered it last toward the detector
    for sig, flux in zip(sums.signature.tolist(), sums.mean_flux()):
        if sig != EMPTY:
            by_face[sums.events[sig][-1]] += flux
    carrying = sorted(by_face, key=by_face.get, reverse=True)
    ranked = [row["tag"] for row in summary["faces"]["critical_and_illuminated"]]
    print("faces by stray flux:", [(tags[t].part, tags[t].face, by_face[t] / aperture) for t in carrying[:4]])
    print("critical ∩ illuminated:", [(r["part"], r["face"], r["product_fraction"]) for r in
                                      summary["faces"]["critical_and_illuminated"][:4]])
    assert ranked[0] == carrying[0]
    assert set(carrying[:3]) <= set(ranked[:5])
    # every face that sends stray light is both seen and lit; none is listed as unlit or unseen
    others = {r["tag"] for key in ("critical_unlit", "lit_not_critical") for r in summary["faces"][key]}
    assert not others & set(carrying[:3])
    for row in summary["faces"]["critical_and_illuminated"]:
        assert row["area_mm2"] > 0 and row["etendue_mm2_sr"] > 0 and row["irradiance"] > 0

    result = CliRunner().invoke(app, ["paths", str(out), "--top", "3", "--faces"])
    assert result.exit_code == 0, result.output
    written = sorted(p.name for p in (out / "paths").iterdir())
    assert {"path-01.png", "path-02.png", "path-03.png", "paths.exr", "face-01.png", "faces.exr"} <= set(written)
    assert carrying and np.isfinite(sums.total).all()
