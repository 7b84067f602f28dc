"""`history` in commit order with commits, values and the dirty mark; `compare` exit codes, verdicts,
difference image and refusals — on stored runs, without the tracer."""

import json
import shutil

import numpy as np
import pytest
from typer.testing import CliRunner

from lensmount.cli import app
from lensmount.loop.provenance import collect, resolve_revision
from lensmount.run.results import read_exr, write_summary
from lensmount.run.store import Store
from tests.loop.runs import EXAMPLE, git, paths, write_run

SCENE = "case1-diaphragm-edge"


def _repo(tmp_path):
    repo = tmp_path / "design"
    shutil.copytree(EXAMPLE, repo, ignore=shutil.ignore_patterns("build", ".lensmount"))
    git(repo, "init", "-q")
    return repo


def _provenance(repo, scene) -> dict:
    from lensmount.loop.prepare import read_inputs

    return collect(*read_inputs(repo, scene), scene, argv=["lensmount"]).to_dict()


def _record(repo, value, folder, store_path):
    summary = write_run(folder, value, value * 0.02, prov=_provenance(repo, repo / "scenes" / f"{SCENE}.toml"))
    with Store(store_path) as store:
        store.record(summary, paths(folder))


def test_history_lists_revisions_in_commit_order_and_marks_a_dirty_tree(tmp_path, monkeypatch):
    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    repo = _repo(tmp_path)
    store_path = repo / ".lensmount" / "runs.sqlite"
    commits, values = [], {}
    for k, wall in enumerate((2.0, 2.5, 3.0)):  # three revisions of the mount, all committed in the same second
        mount = repo / "mount.toml"
        mount.write_text(mount.read_text() + f"\n# revision {k}\n")
        git(repo, "add", "-A")
        git(repo, "commit", "-qm", f"rev {k}")
        commits.append(git(repo, "rev-parse", "HEAD"))
        values[commits[-1]] = 1e-3 * (k + 1)
    # Runs are recorded out of order (newest revision first): history must still follow the commits.
    for k in (2, 0, 1):
        git(repo, "checkout", "-q", commits[k])
        _record(repo, values[commits[k]], tmp_path / f"run{k}", store_path)
    git(repo, "checkout", "-q", commits[2])
    (repo / "mount.toml").write_text((repo / "mount.toml").read_text() + "\n# not committed\n")
    _record(repo, 7e-3, tmp_path / "dirty", store_path)

    result = CliRunner().invoke(app, ["history", str(repo), "--scene", SCENE, "--plot", str(tmp_path / "h.png")])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.output.splitlines() if any(c[:8] in line for c in commits)]
    assert [next(c for c in commits if c[:8] in line) for line in lines] == [commits[0], commits[1], commits[2],
                                                                             commits[2]]
    assert [f"{values[c]:.4g}" in line for c, line in zip(commits, lines)] == [True, True, True]
    assert "*" not in "".join(lines[:3]) and f"{commits[2][:8]}*" in lines[3] and "0.007" in lines[3]
    assert (tmp_path / "h.png").stat().st_size > 0


def _pair(tmp_path, old, new, **kw):
    a = tmp_path / "a"
    b = tmp_path / "b"
    write_run(a, *old, **kw)
    write_run(b, *new, **kw)
    return a, b


def _compare(*args):
    return CliRunner().invoke(app, ["compare", *map(str, args)])


def test_regression_exits_1_with_a_signed_difference_image(tmp_path):
    a, b = _pair(tmp_path, (1.0e-3, 1e-5), (1.5e-3, 1e-5))
    result = _compare(a, b, "--tolerance", "5%", "--confidence", "99%")
    assert result.exit_code == 1, result.output
    assert "regression" in result.output
    report = json.loads((b / "compare" / "compare.json").read_text())
    assert report["verdict"] == "regression" and report["change"] == pytest.approx(5e-4)
    assert report["low"] > report["threshold"] and report["exit_code"] == 1
    diff = read_exr(b / "compare" / "difference.exr")
    assert np.allclose(diff["Y"], 5e-4) and np.allclose(diff["old"], 1e-3) and np.allclose(diff["new"], 1.5e-3)


def test_improvement_and_noise_exit_0(tmp_path):
    a, b = _pair(tmp_path, (1.0e-3, 1e-5), (0.5e-3, 1e-5))
    (a / "checkpoint.npz").write_bytes(b"a checkpoint of another lensmount version")  # only sets the binning
    assert _compare(a, b).exit_code == 0
    assert json.loads((b / "compare" / "compare.json").read_text())["verdict"] == "improvement"


def test_a_change_below_the_noise_is_undecided_and_says_what_would_decide(tmp_path):
    a, b = _pair(tmp_path, (1.0e-3, 2e-4), (1.1e-3, 2e-4))
    result = _compare(a, b, "--out", tmp_path / "c")
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert report["verdict"] == "undecided" and report["more_photons"] > 0
    assert "undecided" in result.output and "more photons" in result.output


def test_runs_of_different_scenes_are_not_comparable(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    write_run(a, 1e-3, 1e-5)
    summary = write_run(b, 1e-3, 1e-5)
    summary["provenance"]["scene_sha256"] = "t" * 64
    (b / "summary.json").write_text(json.dumps(summary))
    result = _compare(a, b)
    assert result.exit_code == 2 and "different scenes" in result.output and "Traceback" not in result.output
    assert not (b / "compare").exists()


def test_different_detectors_are_not_comparable(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    write_run(a, 1e-3, 1e-5)
    write_run(b, 1e-3, 1e-5, image=np.zeros((8, 8)))
    result = _compare(a, b)
    assert result.exit_code == 2 and "detector" in result.output
    assert not (b / "compare").exists()


@pytest.mark.parametrize("args,field", [(["--tolerance", "lots"], "--tolerance"), (["--confidence", "1.5"],
                                         "--confidence"), (["--metric", "beauty"], "--metric")])
def test_bad_options_exit_2(tmp_path, args, field):
    a, b = _pair(tmp_path, (1.0e-3, 1e-5), (1.0e-3, 1e-5))
    result = _compare(a, b, *args)
    assert result.exit_code == 2 and field in result.output


def test_against_a_revision_uses_the_store_and_reuses_the_current_run(tmp_path, monkeypatch):
    # The current design state was simulated before (same input hash in the store): compare must
    # reuse that run, not simulate again, and take the old one from the store by git revision.
    from lensmount.loop.prepare import read_inputs
    from lensmount.loop.simulate import SimulateOptions, planned_input_hash

    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    repo = _repo(tmp_path)
    git(repo, "add", "-A")
    git(repo, "commit", "-qm", "old")
    old_commit = git(repo, "rev-parse", "HEAD")
    scene = repo / "scenes" / f"{SCENE}.toml"
    store_path = repo / ".lensmount" / "runs.sqlite"
    prov = _provenance(repo, scene)
    with Store(store_path) as store:
        store.record(write_run(tmp_path / "old", 1e-3, 1e-5, prov=prov, input_hash="old"), paths(tmp_path / "old"))
    (repo / "mount.toml").write_text((repo / "mount.toml").read_text() + "\n# new revision\n")
    git(repo, "commit", "-qam", "new")
    digest = planned_input_hash(SimulateOptions(repo, scene), *read_inputs(repo, scene))
    with Store(store_path) as store:
        store.record(write_run(tmp_path / "new", 2e-3, 1e-5, prov=_provenance(repo, scene),
                               input_hash=digest), paths(tmp_path / "new"))
    result = _compare(repo, "--scene", SCENE, "--against", "HEAD~1")
    assert result.exit_code == 1, result.output
    rows = repo / ".lensmount" / "rows"  # each row's own copy of its artefacts, never written again:
    assert not (rows / "2" / "compare").exists()  # the comparison goes to the run's own folder
    report = json.loads((tmp_path / "new" / "compare" / "compare.json").read_text())
    assert report["old_run"] == str(rows / "1") and report["new_run"] == str(rows / "2")
    assert report["old"] == 1e-3 and report["new"] == 2e-3
    assert f"old: stored run 1 (HEAD~1;" in result.output and "new: stored run 2 (same design and test condition;" \
        in result.output  # said before it compares
    assert not (repo / "build").exists()  # nothing was simulated
    assert resolve_revision(repo, "HEAD~1") == old_commit and resolve_revision(repo, "nonsense") is None
    bad = _compare(repo, "--scene", SCENE, "--against", "deadbeef")
    assert bad.exit_code == 2 and old_commit[:10] in bad.output


def test_provenance_hashes_each_input_and_ignores_outputs_for_dirty(tmp_path):
    import hashlib

    repo = _repo(tmp_path)
    scene = repo / "scenes" / f"{SCENE}.toml"
    assert _provenance(repo, scene)["git_commit"] is None  # a repository without commits has no HEAD
    git(repo, "add", "-A")
    git(repo, "commit", "-qm", "one")
    (repo / "build").mkdir()
    (repo / "build" / "mesh.npz").write_bytes(b"output")  # outputs inside the folder are not inputs
    p = _provenance(repo, scene)
    assert p["git_commit"] == git(repo, "rev-parse", "HEAD") and p["git_dirty"] is False
    for key, name in (("lens_sha256", "lens.toml"), ("mount_sha256", "mount.toml")):
        assert p[key] == hashlib.sha256((repo / name).read_bytes()).hexdigest()
    assert p["scene_sha256"] == hashlib.sha256(scene.read_bytes()).hexdigest()
    assert p["design_path"] == str(repo.resolve()) and p["design_name"] == "design" and p["scene_name"] == SCENE
    scene.write_text(scene.read_text() + "\n# edited\n")
    assert _provenance(repo, scene)["git_dirty"] is True


def test_bias_bounds_from_the_summaries_widen_the_interval(tmp_path):
    # A change of 10 σ is a regression on the standard errors alone, but not with bias bounds that
    # reach across the tolerance: compare must read them (total and per part) from summary.json.
    a, b = _pair(tmp_path, (1.0e-3, 1e-6), (1.1e-3, 1e-6))
    assert _compare(a, b).exit_code == 1
    for folder in (a, b):
        s = json.loads((folder / "summary.json").read_text())
        s["stray_fraction_bias_bound"] = 1e-4
        s["per_part"]["barrel"]["bias_bound"] = 1e-4
        write_summary(folder / "summary.json", s)  # with a new checksum: an edit without one reads as damage
    result = _compare(a, b, "--out", tmp_path / "c")
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert report["verdict"] == "undecided" and report["more_photons"] is None
    assert report["high"] - report["low"] > 4e-4
    assert report["per_part"]["barrel"]["verdict"] == "undecided"


def test_until_decided_gives_a_run_whose_error_is_unknown_more_passes_instead_of_giving_up(tmp_path, monkeypatch):
    """A run whose kernel bias the ladder cannot bound at 8 passes has an unknown error: nothing is decided on
    it, but twice its passes may bound it; --until-decided asks for them (within the budget) and looks again."""
    import lensmount.loop.compare as loop_compare
    from lensmount.loop.compare import CompareOptions, Run, compare_until_decided
    from lensmount.run.results import write_summary
    from tests.loop.runs import write_run

    old = write_run(tmp_path / "old", 1.0e-3, 1e-5, passes=8)
    write_summary(tmp_path / "old" / "summary.json", old | {"stray_fraction_bias_unbounded": "the ladder's shape"})
    write_run(tmp_path / "new", 1.5e-3, 1e-5, passes=8)
    asked = []

    def resume(run, more, o, observer=None):  # the longer run: its bias bounded now
        asked.append((run.folder.name, more))
        longer = tmp_path / f"{run.folder.name}-longer"
        shutil.copytree(run.folder, longer)
        s = dict(run.summary, passes=run.summary["passes"] + more, stray_fraction_bias_unbounded=None)
        s.pop("sha256", None)
        write_summary(longer / "summary.json", s)
        return Run(longer, s)

    monkeypatch.setattr(loop_compare, "resume", resume)
    monkeypatch.setattr(loop_compare, "not_resumable", lambda folder, summary, store: None)
    result = compare_until_decided(CompareOptions(tmp_path / "old", tmp_path / "new", budget_s=1e6), write=False)
    assert asked == [("old", 8)], asked
    assert result.verdict.verdict == "regression" and result.stopped == "", (result.verdict, result.notes)
