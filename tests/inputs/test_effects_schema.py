"""`[effects]`: scatter = true | false | [selectors], ghosts = true | false | { order = 2 | 3 }, direct.

Selectors are checked against the built assembly; a bad one is one paragraph naming the scene
file, `effects.scatter` and its line, exit 2 (through `lensmount simulate`)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from lensmount.design.scene import scene_from_dict
from lensmount.errors import InputError
from lensmount.scene.build import effects_of
from tests.inputs.conftest import SCENE, simulate, wrote_nothing


def _effects(table: dict):
    data = tomllib.loads(SCENE)
    data["effects"] = table
    return scene_from_dict(data, file="scene.toml").effects


def test_old_booleans_still_mean_what_they_meant():
    e = effects_of(_effects({"scatter": True, "ghosts": True, "direct": False}))
    assert (e.scatter, e.ghosts, e.direct, e.scatterers, e.ghost_order) == (True, True, False, (), 2)
    e = effects_of(_effects({"scatter": False}))
    assert (e.scatter, e.ghosts, e.direct) == (False, False, False)


def test_selectors_and_ghost_order():
    e = effects_of(_effects({"scatter": ["part:spacer-1", "role:diaphragm-edge", "finish:black-anodised"],
                             "ghosts": {"order": 3}, "direct": True}))
    assert e.scatter and e.scatterers == ("part:spacer-1", "role:diaphragm-edge", "finish:black-anodised")
    assert e.ghosts and e.ghost_order == 3 and e.direct
    assert effects_of(_effects({"ghosts": {}})).ghost_order == 2


@pytest.mark.parametrize("table, words", [
    ({"scatter": ["diaphragm-edge"]}, ["scatter selector 'diaphragm-edge' is not understood", '"role:NAME"']),
    ({"scatter": ["colour:red"]}, ["'colour:red' is not understood"]),
    ({"scatter": []}, ["scatter = false"]),
    ({"ghosts": {"order": 4}}, ["effects.ghosts"]),
    ({"ghosts": {"orders": 2}}, ["orders"]),
])
def test_malformed_effects_are_input_errors(table, words):
    with pytest.raises(InputError) as err:
        _effects(table)
    text = err.value.paragraph()
    assert "scene.toml" in text and "effects" in text
    for w in words:
        assert w in text, (w, text)


def test_selectors_pick_the_faces_they_name(cooke_built):
    from lensmount.mesh import TaggedMesh
    from lensmount.scene.scene import Effects, scatterer_mask

    _, geometry = cooke_built
    tags = TaggedMesh.load(geometry / "mesh.npz").tag_table
    finishes = ["" if t.role == "optical" else ("edge" if t.role == "diaphragm-edge" else "black") for t in tags]
    edge = np.array([t.role == "diaphragm-edge" for t in tags])
    assert edge.any()
    mask = scatterer_mask(Effects(scatterers=("role:diaphragm-edge",)), tags, finishes)
    assert np.array_equal(mask, edge)
    assert np.array_equal(scatterer_mask(Effects(scatterers=("finish:edge",)), tags, finishes), edge)
    barrel = np.array([t.part == "barrel" and t.role != "optical" for t in tags])
    mask = scatterer_mask(Effects(scatterers=("part:barrel", "role:diaphragm-edge")), tags, finishes)
    assert np.array_equal(mask, barrel | edge)
    assert not scatterer_mask(Effects(scatter=False, scatterers=("part:barrel",)), tags, finishes).any()
    optical = np.array([t.role == "optical" for t in tags])
    assert not scatterer_mask(Effects(scatterers=("part:lens-1",)), tags, finishes)[optical].any()


@pytest.mark.parametrize("selector, field_word, listed", [
    ('"part:spacer-9"', "part:spacer-9", ["barrel", "housing"]),
    ('"role:diafragm-edge"', "did you mean 'role:diaphragm-edge'", ["lens-edge"]),
    ('"finish:black-anodised"', "finish:black-anodised", ["absorber", "edge-lambert-10"]),
])
def test_unknown_scatterer_is_one_paragraph_exit_2(cooke, selector, field_word, listed):
    """The test design assigns every face absorber or edge-lambert-10: no face has black-anodised."""
    design, out = cooke
    scene = design / "scenes" / "test.toml"
    text = scene.read_text()
    scene.write_text(text.replace("[run]", f"[effects]\nscatter = [{selector}]\n\n[run]", 1))
    line = text[: text.index("[run]")].count("\n") + 2
    res = simulate(design, out)
    assert res.exit_code == 2 and "Traceback" not in res.output, res.output
    msg = [ln for ln in res.output.splitlines() if ln.startswith("error: ")][0]
    assert str(scene) in msg and f"line {line}" in msg and "field 'effects.scatter'" in msg, msg
    assert "names no face" in msg and field_word in msg, msg
    for word in listed:
        assert word in msg, (word, msg)
    assert wrote_nothing(out)
