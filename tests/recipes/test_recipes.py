"""The recipes of docs/architecture.md, done once: a BSDF, a source, an integrator and a CLI verb, each a file of a
user's plug-in package (plugins/, whose dist-info declares them under the entry points `lensmount.plugins`),
found by lensmount itself in a fresh process and used through the paths a user takes: a scene file naming them,
`simulate --method`, `lensmount --help`. A template kind added in a file of its own (knife_ring.py) builds
through the CAD layer's generic path.

The plug-ins run in subprocesses only: registered in this process they would show in other tests' registries.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))

from knife_ring import KnifeRing  # noqa: E402

from lensmount.mesh import TaggedMesh  # noqa: E402

HERE = Path(__file__).parent
PLUGINS = HERE / "plugins"
DESIGN = Path(__file__).resolve().parents[2] / "examples" / "double-gauss-360"


def as_user(*args: str) -> subprocess.CompletedProcess:
    """`args` run in a fresh Python whose path holds the installed plug-in package."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(PLUGINS)] + sys.path))
    return subprocess.run([sys.executable, *args], capture_output=True, text=True, env=env, timeout=900)


def lensmount(*args: str) -> subprocess.CompletedProcess:
    return as_user("-c", "import sys; from lensmount.cli import main; sys.argv[0] = 'lensmount'; main()", *args)


@pytest.fixture(scope="module")
def session() -> dict:
    done = as_user(str(HERE / "user_session.py"))
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def test_a_plug_in_bsdf_is_named_by_a_scene_file_and_samples_its_own_density(session):
    bsdf = session["bsdf"]
    assert bsdf["type"] == "UniformDiffuse" and bsdf["reflectance"] == 0.3
    assert abs(bsdf["mean_weight"] - 0.3) < 4 * bsdf["weight_se"]  # E[f cos / pdf] = albedo = ρ
    assert bsdf["weight_is_f_cos_over_pdf"] and bsdf["pdf_matches"]
    assert session["bsdf_error"]["field"] == "finishes.paint.reflectance"  # checked by its own parameter model


def test_a_plug_in_source_is_read_from_a_scene_file_with_its_own_keys(session):
    error = session["source_keys_error"]
    assert error["field"] == "source.beam_radius" and "beam_radius_mm" in error["detail"]
    assert "applies to type = 'sun' only" in session["source_other_kind_error"]["detail"]


def test_the_plug_in_source_delivers_its_flux_through_an_open_aperture(session):
    """A 2 mm beam through an empty tube onto a detector that catches all of it: the detector
    receives π r² (E·mm²), whatever the tilt's share of the opening (energy conservation)."""
    for total in session["beam_flux"]:
        assert total == pytest.approx(math.pi * 2.0**2, rel=1e-9)


def test_a_plug_in_integrator_is_chosen_by_name_and_checks_its_parameters(session):
    assert session["integrator"]["same_image"] and session["integrator"]["flux"] > 0
    assert session["integrator_params_error"]["field"] == "batch"


def test_a_plug_in_verb_shows_in_help_and_reports_bad_input_as_one_paragraph():
    help_text = lensmount("--help")
    assert help_text.returncode == 0 and "tis " in help_text.stdout and "Total integrated scatter" in help_text.stdout
    done = lensmount("tis", "lambertian", "reflectance=0.25")
    assert done.returncode == 0 and done.stdout.strip() == "0.25", done.stderr
    bad = lensmount("tis", "lambertian", "reflectance=2")
    assert bad.returncode == 2 and "reflectance" in bad.stderr and "Traceback" not in bad.stderr


@pytest.mark.slow  # two short simulations of the example (and its mount's build the first time)
def test_simulate_method_runs_a_plug_in_integrator_in_its_workers(tmp_path):
    """`simulate --method light-tracing` with two worker processes: each finds the plug-in itself, and
    on a scene without ghosts the run is forward's to the bit."""
    scene = tmp_path / "small.toml"
    scene.write_text((DESIGN / "scenes" / "case2-lambertian.toml").read_text().replace("[600, 600]", "[40, 40]"))
    summaries = {}
    for method in ("light-tracing", "forward"):
        done = lensmount("simulate", str(DESIGN), "--scene", str(scene), "--out", str(tmp_path / method),
                         "--method", method, "--passes", "2", "--photons-per-pass", "4000", "--seed", "3",
                         "--workers", "2", "--no-record")
        assert done.returncode == 0, done.stderr
        summaries[method] = json.loads((tmp_path / method / "summary.json").read_text())
    assert summaries["light-tracing"]["method"] == "light-tracing"
    assert summaries["light-tracing"]["stray_fraction"] == summaries["forward"]["stray_fraction"] > 0


def test_a_template_in_its_own_file_builds_a_valid_tagged_solid():
    """The CAD layer's generic path (revolve, face roles from the profile, tessellation with a tag
    per CAD face) takes the new template as it takes the built-in ones."""
    from lensmount.cad.tessellate import tessellate_part
    from lensmount.templates.profile import face_roles

    ring = KnifeRing(z=10.0, bore_radius=8.0, outer_radius=14.0, thickness=1.5)
    solid = ring.build()
    assert solid.is_valid
    roles = face_roles(solid, ring.segments())
    assert ("vane-edge", -1) in roles
    mesh = tessellate_part(solid, "knife-ring-1", "vane", "black-anodised", roles, 0.05, 5.0)
    assert isinstance(mesh, TaggedMesh)
    edge = [k for k, t in enumerate(mesh.tag_table) if t.role == "vane-edge"]
    assert len(edge) == 1 and np.isin(mesh.tags, edge).any()
    r = np.hypot(mesh.vertices[:, 0], mesh.vertices[:, 1])
    assert r.min() == pytest.approx(8.0, abs=0.05) and r.max() == pytest.approx(14.0, abs=1e-6)
