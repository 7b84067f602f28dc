"""The one registry idiom: create by name from checked parameters; unknown names and keys are one InputError."""

import os
import subprocess
import sys

import pytest
from pydantic import BaseModel, ConfigDict, Field

from lensmount.errors import InputError
from lensmount.registry import Registry


class _Params(BaseModel):
    model_config = ConfigDict(extra="forbid")
    reflectance: float = Field(0.05, ge=0, le=1)


def _registry():
    kinds = Registry("finish model", where="finishes.toml's model")

    @kinds.register("grey", _Params)
    def grey(params: _Params, scale: float = 1.0) -> float:
        """A grey finish."""
        return params.reflectance * scale

    return kinds


def test_create_checks_parameters_and_passes_context():
    kinds = _registry()
    assert kinds.create("grey", {"reflectance": 0.5}, scale=2.0) == 1.0
    assert kinds.names() == ("grey",) and "grey" in kinds and kinds.entry("grey").summary == "A grey finish."


def test_unknown_name_lists_valid_names_with_a_guess():
    with pytest.raises(InputError) as err:
        _registry().create("gray", {}, file="finishes.toml", field="finishes.black.model")
    text = err.value.paragraph()
    assert "'gray'" in text and "did you mean 'grey'" in text and "finishes.toml" in text


def test_unknown_key_and_range_are_input_errors_naming_the_field():
    with pytest.raises(InputError) as err:
        _registry().create("grey", {"reflectanse": 0.1}, field="finishes.black")
    assert err.value.field == "finishes.black.reflectanse" and "reflectance" in err.value.paragraph()
    with pytest.raises(InputError) as err:
        _registry().create("grey", {"reflectance": 1.5}, field="finishes.black")
    assert err.value.field == "finishes.black.reflectance"


def test_a_name_registered_twice_is_refused():
    kinds = _registry()
    with pytest.raises(ValueError):
        kinds.register("grey", _Params)(lambda p: 0.0)


def test_a_wrong_type_names_the_fields_declared_range():
    with pytest.raises(InputError) as err:
        _registry().create("grey", {"reflectance": "high"}, field="finishes.black")
    assert err.value.field == "finishes.black.reflectance" and err.value.valid == "a number >= 0 and <= 1"


def test_the_built_ins_are_every_module_of_the_registrys_package(tmp_path, monkeypatch):
    """A new file in the folder registers itself: nobody imports it by name."""
    package = tmp_path / "finish_kinds"
    package.mkdir()
    (package / "__init__.py").write_text(
        "from lensmount.registry import Registry\n"
        "KINDS = Registry('finish model', where='a finish', implementations='finish_kinds')\n")
    (package / "velvet.py").write_text(
        "from pydantic import BaseModel\nfrom finish_kinds import KINDS\n\n\n"
        "class VelvetParams(BaseModel):\n    pass\n\n\n"
        "@KINDS.register('velvet', VelvetParams)\ndef velvet(params):\n    return 'velvet'\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import finish_kinds

    assert finish_kinds.KINDS.names() == ("velvet",) and finish_kinds.KINDS.create("velvet", {}) == "velvet"


def test_a_plug_in_that_fails_to_load_is_one_paragraph_naming_its_entry_point(tmp_path):
    """A user's package declaring a plug-in (entry point lensmount.plugins) whose module raises on import."""
    info = tmp_path / "broken_plugin-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text("[lensmount.plugins]\nvelvet = broken_velvet\n")
    (tmp_path / "broken_velvet.py").write_text("raise RuntimeError('no velvet today')\n")
    script = ("from lensmount.errors import InputError\nfrom lensmount.registry import load_plugins\n"
              "try:\n    load_plugins()\nexcept InputError as e:\n    print(e.paragraph())\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path)] + sys.path))
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, check=True)
    assert "velvet" in done.stdout and "no velvet today" in done.stdout and "lensmount.plugins" in done.stdout
