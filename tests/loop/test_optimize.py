"""optimize: the [optimize] table's errors, an infeasible candidate explained, common random numbers shrinking
a difference's variance on the reference design, and a tiny study on the Cooke triplet: a resumed study ends
where an uninterrupted one does, and the verdict runs on a seed the search never used."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.errors import InputError
from lensmount.loop.optimize import OptimizeOptions, Search, crn_effect, optimize, start_values
from lensmount.loop.optimize_spec import load_optimize
from lensmount.loop.simulate import Observer

ROOT = Path(__file__).resolve().parents[2]
TRIPLET = ROOT / "examples" / "cooke-triplet"
REFERENCE = ROOT / "examples" / "double-gauss-360"
CRN_SPEC = """
[optimize]
[optimize.objective]
scene = "case2-lambertian"
[optimize.variables]
"hood.length_mm" = { low = 60.0, high = 140.0 }
[optimize.fidelity]
photons_per_pass = 4000
"""

# The start's hood is 10 mm, so the mount is 73 mm long: a hood over 17 mm breaks max_length_mm = 80.
SPEC = """
[optimize]
trials = 4

[optimize.objective]
scene = "case2-lambertian"

[optimize.variables]
"hood.length_mm" = { low = 5.0, high = 40.0 }
"vanes.count" = { low = 1, high = 3, integer = true }

[optimize.constraints]
max_length_mm = 80.0

[optimize.fidelity]
photons_per_pass = 4000
passes = [3, 6]
final_passes = 6

[optimize.search]
sampler_seed = 3
"""


def design(folder: Path, spec: str = SPEC) -> Path:
    shutil.copytree(TRIPLET, folder, ignore=shutil.ignore_patterns("build", ".lensmount"))
    mount = folder / "mount.toml"
    mount.write_text(mount.read_text().replace("length_mm = 20.0", "length_mm = 10.0"))
    (folder / "optimize.toml").write_text(spec)
    return folder


@pytest.mark.parametrize("edit, field, words", [
    ('trials = 4', "optimize.trails", "did you mean 'trials'"),
    ('"vanes.count" = { low = 1, high = 3, integer = true }', "optimize.variables.vanes.count",
     "low < high"),
    ('scene = "case2-lambertian"', "optimize.objective.kind", "stray_fraction"),
    ('max_length_mm = 80.0', "optimize.constraints.max_length_mm", "> 0"),
    ('passes = [3, 6]', "optimize.fidelity.passes", "must rise"),
    ('"hood.length_mm" = { low = 5.0, high = 40.0 }', "optimize.variables.vanes.finish.finishes", "black-paint"),
])
def test_a_bad_table_is_one_paragraph_naming_the_field(tmp_path, edit, field, words):
    bad = {
        'trials = 4': 'trails = 4',
        '"vanes.count" = { low = 1, high = 3, integer = true }':
            '"vanes.count" = { low = 3, high = 3, integer = true }',
        'scene = "case2-lambertian"': 'scene = "case2-lambertian"\nkind = "pst"',
        'max_length_mm = 80.0': 'max_length_mm = -1.0',
        'passes = [3, 6]': 'passes = [6, 3]',
        '"hood.length_mm" = { low = 5.0, high = 40.0 }': '"vanes.finish" = { finishes = ["blak-paint"] }',
    }[edit]
    folder = design(tmp_path / "d", SPEC.replace(edit, bad))
    with pytest.raises(InputError) as caught:
        load_optimize(folder)
    error = caught.value
    assert error.file == str(folder / "optimize.toml")
    assert (error.field or "").startswith(field.rsplit(".", 1)[0]) and words in error.paragraph()
    result = CliRunner().invoke(app, ["optimize", str(folder), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_infeasible_candidates_are_explained_not_crashed(tmp_path):
    folder = design(tmp_path / "d")
    search = Search(OptimizeOptions(folder, out=tmp_path / "out"), load_optimize(folder), Observer())
    long = search.candidate(0, {"hood.length_mm": 30.0, "vanes.count": 2}, tmp_path / "out" / "long")
    # the start is 73 mm long with a 10 mm hood: 20 mm more hood, 20 mm more mount
    assert not long.feasible and re.search(r"overall length (92\.9|93\.0)\d mm > 80 mm", long.why)
    broken = search.candidate(1, {"hood.length_mm": -4.0, "vanes.count": 2}, tmp_path / "out" / "broken")
    assert not broken.feasible and "hood.length_mm" in broken.why  # the mount's own validation, in its words


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    """The same study run straight through, and stopped after one candidate then resumed."""
    base = tmp_path_factory.mktemp("optimize")
    straight = optimize(OptimizeOptions(design(base / "a"), out=base / "a-out"))
    folder = design(base / "b")
    first = optimize(OptimizeOptions(folder, out=base / "b-out", budget=1))
    resumed = optimize(OptimizeOptions(folder, out=base / "b-out"))
    return straight, first, resumed, base


@pytest.mark.slow
def test_common_random_numbers_shrink_the_variance_of_a_difference(tmp_path):
    """The reference design and its hood 0.8 mm shorter: pass i of both starts the same photons, so most of
    their noise cancels in the difference; with independent seeds the variances add."""
    folder = tmp_path / "dg"
    shutil.copytree(REFERENCE, folder, ignore=shutil.ignore_patterns("build", ".lensmount"))
    (folder / "optimize.toml").write_text(CRN_SPEC)
    spec = load_optimize(folder)
    search = Search(OptimizeOptions(folder, out=tmp_path / "out"), spec, Observer())
    start = search.candidate(-1, start_values(folder, spec.variables), tmp_path / "out" / "start")
    crn = crn_effect(search, start, tmp_path / "out", 8)
    assert crn.passes == 8 and crn.nearby["hood.length_mm"] == pytest.approx(99.2)
    assert crn.ratio < 0.5, (crn.shared_variance, crn.independent_variance)


@pytest.mark.slow
def test_a_resumed_study_ends_where_an_uninterrupted_one_does(studies):
    straight, first, resumed, _ = studies
    assert not first.finished and len(first.candidates) == 1
    assert resumed.finished and len(resumed.candidates) == len(straight.candidates) == 4
    assert [c.values for c in resumed.candidates] == [c.values for c in straight.candidates]
    assert [c.runs for c in resumed.candidates] == [c.runs for c in straight.candidates]
    assert resumed.best.values == straight.best.values


@pytest.mark.slow
def test_an_infeasible_candidate_of_the_search_is_in_the_report(studies):
    straight, *_, base = studies
    report = json.loads((base / "a-out" / "optimize.json").read_text())
    bad = [c for c in report["candidates"] if not c["feasible"]]
    assert bad and all("overall length" in c["why"] and c["value"] is None for c in bad)
    assert straight.best.feasible


@pytest.mark.slow
def test_the_verdict_runs_on_a_seed_the_search_never_used(studies):
    straight, *_, base = studies
    out = base / "a-out"
    used = {json.loads(p.read_text())["seed"] for p in out.glob("**/summary.json") if "verdict" not in str(p)}
    assert used == set(straight.search_seeds)
    if straight.best is straight.start:
        pytest.skip("no candidate beat the start: there is no verdict to run")
    verdict_runs = [out / "best" / "verdict-run", out / "start" / "verdict-run"]
    assert {json.loads((r / "summary.json").read_text())["seed"] for r in verdict_runs} == {straight.verdict_seed}
    assert straight.verdict_seed not in used
    assert straight.verdict is not None and straight.verdict.confidence == 0.99
    assert (straight.revision / "mount.toml").is_file() and list((out / "best" / "build").glob("parts/*.step"))
    assert straight.run_id is not None and (base / "a" / ".lensmount" / "runs.sqlite").is_file()  # the start's store
