"""`lensmount watch`: edits seen as a user saves them, and a revision judged against the baseline."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from lensmount.loop.watch import WatchOptions, changed_files, snapshot, wait_for_edit, watch

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "lensmount" / "examples"


def test_only_input_files_count_and_a_save_in_steps_is_one_edit(tmp_path):
    (tmp_path / "mount.toml").write_text("name = 'm'\n")
    (tmp_path / "build").mkdir()
    (tmp_path / "build" / "mesh.npz").write_bytes(b"x")  # outputs are no edit
    (tmp_path / ".lensmount").mkdir()
    (tmp_path / ".lensmount" / "runs.sqlite").write_bytes(b"x")
    before = snapshot(tmp_path)
    assert list(before) == ["mount.toml"]

    steps = iter([lambda: None,  # first look: nothing yet
                  lambda: (tmp_path / "mount.toml").write_text(""),  # the editor truncates ...
                  lambda: (tmp_path / "mount.toml").write_text("name = 'new'\n[hood]\nlength_mm = 5.0\n"),  # ... writes
                  lambda: (tmp_path / "build" / "mesh.npz").write_bytes(b"yy"),
                  lambda: None])

    def sleep(_):
        next(steps, lambda: None)()

    after, changed = wait_for_edit(tmp_path, before, 0.0, 0.0, sleep=sleep)
    assert changed == ("mount.toml",)
    assert "length_mm" in (tmp_path / "mount.toml").read_text() and after == snapshot(tmp_path)
    assert changed_files(after, after) == ()


@pytest.mark.slow  # a baseline and two revisions of the Cooke triplet, each regenerated and simulated
def test_a_saved_edit_is_judged_and_a_broken_one_is_explained(tmp_path):
    design = tmp_path / "cooke"
    shutil.copytree(EXAMPLES / "cooke-triplet", design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    scene = design / "scenes" / "watch.toml"
    scene.write_text('[source]\ntype = "sun"\noff_axis_deg = 25.0\n[detector]\npixels = [36, 24]\n'
                     '[effects]\nscatter = true\n[run]\nphotons = 4000\npasses = 3\nseed = 1\n')
    mount = design / "mount.toml"
    text = mount.read_text()
    edits = iter([text.replace("length_mm = 20.0", "length_mm = 4.0"),
                  text.replace("length_mm = 20.0", "length_mm = -4.0")])

    def save(d, before):  # what an engineer's save does, then watch's own look at the folder
        mount.write_text(next(edits))
        now = snapshot(d)
        return now, changed_files(before, now)

    # budget 0: the first look is the verdict (the looks until decided are compare's own tests)
    revisions = watch(WatchOptions(design, "watch", workers=1, out=tmp_path / "watch", budget_s=0.0), wait=save)
    baseline = next(revisions)
    assert baseline.number == 0 and baseline.error is None
    shorter = next(revisions)
    assert shorter.changed == ("mount.toml",) and shorter.error is None
    assert shorter.result.verdict.verdict in ("regression", "no regression", "improvement", "undecided")
    assert shorter.result.old.folder != shorter.result.new.folder
    broken = next(revisions)
    assert broken.result is None and "length_mm" in broken.error
    page = (tmp_path / "watch" / "watch.html").read_text()
    assert 'http-equiv="refresh"' in page and "did not build" in page and "revision-001" in page


def test_the_terminal_says_why_a_revision_is_undecided_and_what_would_decide_it(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    import lensmount.cli.watch as cli_watch
    from lensmount.analysis.compare import Verdict
    from lensmount.cli import app
    from lensmount.loop.compare import CompareResult, Run
    from lensmount.loop.watch import Revision

    verdict = Verdict("undecided", 1e-4, 1.1e-4, 1e-5, 0.1, -1e-5, 3e-5, 5e-6, 0.99,
                      note="about 3500 more passes of the old run and 4400 more passes of the new run would decide it")
    result = CompareResult(Run(tmp_path / "a", {}), Run(tmp_path / "b", {}), verdict, {}, "stray_fraction",
                           stopped="the budget is spent (118 of 120 s): ... --budget 9000 or more would run them")

    unbudgeted = CompareResult(Run(tmp_path / "a", {}), Run(tmp_path / "b", {}), verdict, {}, "stray_fraction")

    def revisions(options, observer):
        yield Revision(0, (), None, None, 1.0)
        yield Revision(1, ("mount.toml",), result, None, 2.0)
        yield Revision(2, ("finishes.toml",), unbudgeted, None, 2.0)

    monkeypatch.setattr(cli_watch, "watch_design", revisions)
    out = CliRunner().invoke(app, ["watch", str(tmp_path), "--scene", "s"])
    assert out.exit_code == 0, out.output
    assert "revision 1 (mount.toml" in out.output and "undecided" in out.output
    said = out.output.split("revision 2")
    assert "--budget 9000 or more" in said[0] and "4400 more passes" not in said[0]  # said once, by the budget's line
    assert "4400 more passes of the new run would decide it" in said[1]
