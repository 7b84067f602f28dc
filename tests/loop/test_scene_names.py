"""`simulate --scene` takes a scene's name from DESIGN/scenes/ as `compare` and `watch` do; a name that is
neither a file nor a scene of the design is refused with the design's scenes listed."""

import shutil

from typer.testing import CliRunner

from lensmount.cli import app
from tests.loop.runs import EXAMPLE


def test_simulate_takes_a_scene_name_and_lists_the_scenes_for_an_unknown_one(tmp_path):
    design = tmp_path / "design"
    shutil.copytree(EXAMPLE, design, ignore=shutil.ignore_patterns("build", ".lensmount"))
    unknown = CliRunner().invoke(app, ["simulate", str(design), "--scene", "case3", "--no-record"])
    assert unknown.exit_code == 2 and "Traceback" not in unknown.output, unknown.output
    assert "scene 'case3' not found" in unknown.output
    assert "case1-diaphragm-edge, case2-lambertian" in unknown.output
    # a name of the design's: read, then refused for the next thing wrong (an --out that is a file)
    (tmp_path / "a-file").write_text("")
    named = CliRunner().invoke(app, ["simulate", str(design), "--scene", "case2-lambertian", "--no-record",
                                     "--out", str(tmp_path / "a-file")])
    assert named.exit_code == 2 and "--out" in named.output and "not found" not in named.output, named.output
    assert not (design / "build").exists()
