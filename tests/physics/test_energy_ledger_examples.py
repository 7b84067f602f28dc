"""The energy ledger balances on every example scene (every example design, all their scenes),
through the whole simulate path (CAD, scene build, runner, summary.json), for both methods."""

import json
import shutil
from pathlib import Path

import pytest

from lensmount.loop.simulate import SimulateOptions, simulate

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
CASES = [(d.name, s.name) for d in sorted(EXAMPLES.iterdir()) if d.is_dir()
         for s in sorted((d / "scenes").glob("*.toml"))]


@pytest.fixture(scope="module")
def designs(tmp_path_factory):
    """Copies of the example designs; their geometry is built once (DESIGN/build) and reused."""
    base = tmp_path_factory.mktemp("ledger-examples")
    return {name: Path(shutil.copytree(EXAMPLES / name, base / name,
                                       ignore=shutil.ignore_patterns("build", ".lensmount")))
            for name in {d for d, _ in CASES}}


@pytest.mark.slow
@pytest.mark.parametrize("method", ["forward", "bidirectional"])
@pytest.mark.parametrize("design,scene", CASES)
def test_energy_ledger_balances_on_every_example_scene(designs, tmp_path, design, scene, method):
    folder = designs[design]
    result = simulate(SimulateOptions(folder, folder / "scenes" / scene, method=method, out=tmp_path / "out",
                                      passes=1, photons_per_pass=3000, workers=1, record=False))
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    ledger = summary["energy_ledger"]
    entries = ledger["entries"]
    assert entries["source"] > 0 and abs(ledger["residual_rel"]) < 1e-9, ledger
    assert summary["estimator_settings"]["samples_per_pixel"] == 1 and result.summary["method"] == method
    if method == "forward":  # the film holds what the ledger says reached the detector, plus the ghost routes
        routes = sum(r["fraction"] for r in summary["ghost_pairs"]) * summary["aperture_flux_mm2"]
        for part, values in summary["per_part"].items():
            expected = entries.get(f"detector/{part}", 0.0) + (routes if part == "ghosts" else 0.0)
            assert expected == pytest.approx(values["flux_mm2"], rel=1e-9, abs=1e-12)


def test_every_example_design_has_scenes():
    # the seed paper's case 3 and the ghost studies are the same lenses and mounts with other finishes:
    # designs of their own (finishes.toml)
    assert {d for d, _ in CASES} == {f"{lens}{treatment}" for lens, treatments in (
        ("cooke-triplet", ("", "-gaussian-paint", "-uncoated")), ("double-gauss-360", ("", "-gaussian-paint", "-mgf2")))
        for treatment in treatments} and len(CASES) == 8
