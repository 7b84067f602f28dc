"""How long a run goes when the command line says nothing: the scene's target with a time cap, the
--quick preset, and the estimate `simulate` gives before it starts."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from lensmount.design.scene import RunSpec, load_scene
from lensmount.loop.progress import expected_s, forecast
from lensmount.loop.simulate import QUICK, SimulateOptions, stopping
from lensmount.run.runner import Stopping
from lensmount.run.store import RunRecord

from tests.inputs.conftest import EXAMPLES, edit, simulate

SCENES = sorted(EXAMPLES.glob("*/scenes/*.toml"))


@pytest.mark.parametrize("path", SCENES, ids=lambda p: f"{p.parent.parent.name}/{p.stem}")
def test_every_example_scene_stops_at_a_target_within_a_time_cap(path):
    run = load_scene(path).run
    assert run.target_rel_error is not None and run.time_s <= 300
    rule = stopping(SimulateOptions(path.parent.parent, path), run)
    assert (rule.target_rel_error, rule.time_s, rule.max_passes) == (run.target_rel_error, run.time_s, run.passes)
    if path.stem.startswith("case"):  # 10⁶ photons per pass made one case-2 regression check take 6–7 minutes
        assert run.photons <= 200_000


def test_a_scene_without_time_s_is_still_capped_and_explicit_rules_replace_the_scene():
    run = RunSpec(passes=5)
    assert stopping(SimulateOptions(Path("d"), Path("s")), run) == Stopping(time_s=600.0, max_passes=5,
                                                                            time_after_passes=3)
    explicit = stopping(SimulateOptions(Path("d"), Path("s"), passes=3), RunSpec(target_rel_error=0.01, time_s=9))
    assert (explicit.target_rel_error, explicit.time_s, explicit.max_passes) == (None, None, 3)


def test_a_cap_stops_no_run_before_it_has_an_error_bar():
    from lensmount.analysis.passes import Accumulator

    acc = Accumulator.empty((1, 1), ["total"], 1.0)
    cap = stopping(SimulateOptions(Path("d"), Path("s"), quick=True), RunSpec())
    for passes, done in ((1, False), (2, False), (3, True)):
        acc.n = passes
        assert cap.done(acc, elapsed=10 * QUICK.time_s) is done
    acc.n = 1
    assert Stopping(time_s=1.0).done(acc, 2.0)  # --time given: a hard stop, as before


def test_quick_changes_the_length_only():
    run = RunSpec(photons=100_000, passes=32, target_rel_error=0.02, time_s=120)
    quick = stopping(SimulateOptions(Path("d"), Path("s"), quick=True), run)
    assert (quick.target_rel_error, quick.time_s, quick.min_passes) == \
        (QUICK.target_rel_error, QUICK.time_s, QUICK.min_passes)
    assert quick.target_rel_error > run.target_rel_error and quick.time_s < run.time_s
    assert quick.min_passes < Stopping.min_passes and quick.max_passes == run.passes
    # a rule given on the command line still wins, with quick's minimum passes
    given = stopping(SimulateOptions(Path("d"), Path("s"), quick=True, time_s=5.0), run)
    assert (given.time_s, given.target_rel_error, given.min_passes) == (5.0, None, QUICK.min_passes)


def _record(passes, photons, time_s, value, std_error, bias=0.0, id=7) -> RunRecord:
    fields = {f: None for f in RunRecord.__dataclass_fields__}
    return RunRecord(**{**fields, "id": id, "passes": passes, "photons": photons, "time_s": time_s,
                        "stray_fraction": value, "stray_fraction_std_error": std_error,
                        "stray_fraction_bias_bound": bias})


def test_the_estimate_scales_a_stored_run_at_one_over_root_photons():
    # 8 passes × 10⁵ read 4 % (std 3 % + bias 1 %) in 80 s: 2 % needs 4× the photons, 32 passes, 320 s
    stored = [_record(8, 800_000, 80.0, 1.0, 0.03, 0.01)]
    seconds, passes, r = expected_s(Stopping(target_rel_error=0.02, max_passes=100), 100_000, stored)
    assert (passes, r.id) == (32, 7) and seconds == pytest.approx(320.0)
    # no fewer than the minimum passes, never beyond the time cap, and the cap is said
    assert expected_s(Stopping(target_rel_error=0.5, max_passes=100), 100_000, stored)[1] == Stopping.min_passes
    capped = Stopping(target_rel_error=0.02, time_s=60.0, max_passes=100)
    assert expected_s(capped, 100_000, stored)[0] == 60.0
    assert "stops at 60 s first" in forecast(capped, 100_000, stored)
    assert "first passes will tell" in forecast(capped, 100_000, [])


def test_the_estimate_says_the_passes_once_and_on_resume_what_is_left():
    stored = [_record(8, 800_000, 80.0, 1.0, 0.03, 0.01)]  # 10 s a pass of 10⁵ photons
    by_passes = forecast(Stopping(max_passes=24), 100_000, stored)
    assert by_passes.startswith("estimate: 24 passes in about 240 s (") and by_passes.count("24 passes") == 1
    resumed = forecast(Stopping(max_passes=24), 100_000, stored, done_passes=20)
    assert resumed.startswith("estimate: 4 more passes (24 in all, 20 done) in about 40 s ("), resumed
    target = forecast(Stopping(target_rel_error=0.02, max_passes=100), 100_000, stored, done_passes=30)
    assert "in about 20 s more, 2 more passes (32 in all, 30 done)" in target, target


def test_simulate_says_how_long_before_it_starts_and_a_quick_run_is_the_same_test(cooke, tmp_path):
    design, out = cooke
    edit(design / "scenes" / "test.toml", "passes = 1", "passes = 3\ntarget_rel_error = 0.5\ntime_s = 60")
    store = tmp_path / "runs.sqlite"
    first = simulate(design, out, "--store", str(store))
    assert first.exit_code == 0, first.output
    assert "estimate: 50 %" in first.output and "no stored run of this scene" in first.output
    second = simulate(design, tmp_path / "quick", "--store", str(store), "--quick")
    assert second.exit_code == 0, second.output
    # the first run read no signal (forward, 6000 photons): no error to scale, so still the first passes tell
    assert re.search(r"estimate: 10 %; stops at 30 s .*the first passes will tell", second.output)
    full, quick = (json.loads((o / "summary.json").read_text()) for o in (out, tmp_path / "quick"))
    assert full["input_hash"] == quick["input_hash"]
    assert full["provenance"]["condition_sha256"] == quick["provenance"]["condition_sha256"]
