"""`lensmount init` and `lensmount regenerate` from the command line."""

import json

from typer.testing import CliRunner

from lensmount.cli import app


def test_init_then_regenerate_cooke(cooke):
    d, out = cooke
    assert (d / "mount.toml").is_file() and (d / "lens.toml").is_file()
    doc = json.loads((out / "manifest.json").read_text())
    names = {p["name"] for p in doc["parts"]}
    assert {"lens-1", "lens-2", "lens-3", "diaphragm", "hood", "housing", "barrel"} <= names
    res = CliRunner().invoke(app, ["regenerate", str(d), "--out", str(out), "--quiet"])
    assert res.exit_code == 0 and "cache" in res.output


def test_bad_mount_exits_2_naming_the_field(tmp_path):
    runner = CliRunner()
    d = tmp_path / "dg"
    assert runner.invoke(app, ["init", str(d)]).exit_code == 0
    text = (d / "mount.toml").read_text().replace("[hood]", "[hood]\ncolour = 'red'")
    (d / "mount.toml").write_text(text)
    res = runner.invoke(app, ["regenerate", str(d), "--quiet"])
    assert res.exit_code == 2
    assert "hood.colour" in res.output and "Traceback" not in res.output


def test_init_refuses_a_non_empty_folder(tmp_path):
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "f").write_text("")
    res = CliRunner().invoke(app, ["init", str(tmp_path / "x")])
    assert res.exit_code == 2


def test_tessellation_options_change_the_mesh_not_the_steps(tmp_path, cooke):
    import shutil

    from lensmount.mesh import TaggedMesh

    runner = CliRunner()
    d, out = tmp_path / "cooke", tmp_path / "out"
    shutil.copytree(cooke[0], d)
    shutil.copytree(cooke[1], out)  # with its cache: the default tessellation is not rebuilt
    assert runner.invoke(app, ["regenerate", str(d), "-o", str(out), "-q"]).exit_code == 0
    coarse = TaggedMesh.load(out / "mesh.npz")
    steps = {p.name: p.read_bytes() for p in (out / "parts").glob("*.step")}
    res = runner.invoke(app, ["regenerate", str(d), "-o", str(out), "-q", "--angular-tolerance", "2"])
    assert res.exit_code == 0, res.output
    fine = TaggedMesh.load(out / "mesh.npz")
    assert len(fine.triangles) > 1.5 * len(coarse.triangles)
    assert {p.name: p.read_bytes() for p in (out / "parts").glob("*.step")} == steps
    res = runner.invoke(app, ["regenerate", str(d), "-o", str(out), "-q", "--angular-tolerance", "90"])
    assert res.exit_code == 2 and "tessellation" in res.output
