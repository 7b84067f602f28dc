"""A stored run keeps its own copy of its inputs: a run of an earlier revision takes more passes after the
design folder has moved on, and `watch` / `compare --until-decided` say why a verdict stays undecided."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from lensmount.loop.compare import CompareOptions, Run, compare, resume
from lensmount.loop.resume import not_resumable
from lensmount.loop.simulate import SimulateOptions, simulate
from lensmount.run.store import Store, default_path

pytestmark = pytest.mark.slow  # each test simulates the Cooke triplet a few times (a few seconds a run)

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "lensmount" / "examples"
SCENE = ('[source]\ntype = "sun"\noff_axis_deg = 25.0\n[detector]\npixels = [36, 24]\n'
         '[effects]\nscatter = true\n[run]\nphotons = 4000\npasses = 3\nseed = 1\n')


def _design(folder: Path) -> Path:
    shutil.copytree(EXAMPLES / "cooke-triplet", folder, ignore=shutil.ignore_patterns("build", ".lensmount"))
    (folder / "scenes" / "small.toml").write_text(SCENE)
    return folder


def _edit_hood(design: Path, length: str) -> None:
    mount = design / "mount.toml"
    mount.write_text(mount.read_text().replace("length_mm = 20.0", f"length_mm = {length}", 1))


def test_a_run_of_an_earlier_revision_continues_on_its_own_copy_of_its_inputs(tmp_path, monkeypatch):
    """3 passes, then the hood edited in the folder, then 2 more passes of the stored run: it continues on
    the inputs it ran on (the same 5 passes as a fresh run of the old design, to the bit) and is still
    recorded as that design's run."""
    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    design = _design(tmp_path / "design")
    first = simulate(SimulateOptions(design, design / "scenes" / "small.toml", out=tmp_path / "run", workers=1))
    mount_before = first.summary["provenance"]["mount_sha256"]
    _edit_hood(design, "30.0")
    run = Run(first.out, first.summary)
    assert not_resumable(run.folder, run.summary) is None
    longer = resume(run, 2, CompareOptions(design, workers=1))
    assert longer.summary["passes"] == 5 and longer.summary["input_hash"] == first.summary["input_hash"]
    prov = longer.summary["provenance"]
    assert prov["design_path"] == str(design.resolve()) and prov["mount_sha256"] == mount_before
    with Store(default_path(design)) as store:
        rows = store.runs(design_path=design)
    assert [r.passes for r in rows] == [3, 5]

    fresh_design = _design(tmp_path / "fresh")  # the old revision from scratch, 5 passes at once
    fresh = simulate(SimulateOptions(fresh_design, fresh_design / "scenes" / "small.toml", out=tmp_path / "fresh-run",
                                     workers=1, passes=5, record=False))
    assert fresh.summary["stray_fraction"] == longer.summary["stray_fraction"]


def test_a_run_without_a_stored_copy_says_why_it_cannot_continue(tmp_path, monkeypatch):
    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    design = _design(tmp_path / "design")
    first = simulate(SimulateOptions(design, design / "scenes" / "small.toml", out=tmp_path / "run", workers=1,
                                     record=False))
    _edit_hood(design, "30.0")
    why = not_resumable(first.out, first.summary)
    assert "changed since it ran" in why and "keeps no copy" in why


def test_an_undecided_verdict_says_what_would_decide_it_and_that_the_budget_is_too_small(tmp_path, monkeypatch):
    """A hood 0.1 mm longer changes nothing measurable: with no budget the verdict stays undecided, and the
    result says that the budget is spent, how many more passes of which run would decide it and the budget
    that would pay for them; the stored run of the design before the edit (--against last) could take them."""
    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    design = _design(tmp_path / "design")
    simulate(SimulateOptions(design, design / "scenes" / "small.toml", method="forward", workers=1,
                             out=tmp_path / "before"))
    _edit_hood(design, "20.1")
    result = compare(CompareOptions(design, scene="small", against="last", method="forward", workers=1,
                                    until_decided=True, budget_s=0.0))
    assert result.verdict.verdict == "undecided", result.verdict
    assert not_resumable(result.old.folder, result.old.summary) is None
    said = result.stopped
    assert said.startswith("the budget is spent (0 of 0 s): ") and "would decide it" in said, (said, result.verdict)
    assert "more passes of the old run" in said and "--budget " in said and said in result.notes


def test_a_checkpoint_of_other_inputs_says_which_file_and_key_changed(tmp_path, monkeypatch):
    from lensmount.errors import InputError

    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    design = _design(tmp_path / "design")
    scene = design / "scenes" / "small.toml"
    simulate(SimulateOptions(design, scene, out=tmp_path / "run", workers=1, record=False))
    _edit_hood(design, "30.0")
    with pytest.raises(InputError) as refused:
        simulate(SimulateOptions(design, scene, out=tmp_path / "run", workers=1, record=False, resume=True))
    assert "mount hood.length_mm: 20 -> 30" in str(refused.value.paragraph()), refused.value.paragraph()
