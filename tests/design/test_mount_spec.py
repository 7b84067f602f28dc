"""mount.toml validation: unknown keys and bad values are InputErrors naming file and field."""

from pathlib import Path

import pytest

from lensmount.design.mount import MountSpec, load_mount, parse_mount
from lensmount.errors import InputError

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_examples_load():
    for name in ("double-gauss-360", "cooke-triplet"):
        spec = load_mount(EXAMPLES / name / "mount.toml")
        assert isinstance(spec, MountSpec)
    spec = load_mount(EXAMPLES / "double-gauss-360" / "mount.toml")
    assert spec.diaphragm.land_mm == pytest.approx(0.05)


def test_unknown_key_is_an_error_naming_the_field(tmp_path: Path):
    f = tmp_path / "mount.toml"
    f.write_text("[vanes]\ncout = 3\n")
    with pytest.raises(InputError) as exc:
        load_mount(f)
    assert exc.value.file == str(f)
    assert exc.value.field == "vanes.cout"
    assert "unknown key" in exc.value.paragraph()


def test_bad_value_names_field_and_valid_range():
    with pytest.raises(InputError) as exc:
        parse_mount({"diaphragm": {"land_mm": 0.0}}, file="m.toml")
    assert exc.value.field == "diaphragm.land_mm"
    assert "> 0" in exc.value.paragraph()


def test_unknown_template_kind():
    with pytest.raises(InputError) as exc:
        parse_mount({"templates": {"widget": "w.py"}})
    assert "templates" in exc.value.field


def test_toml_syntax_error_gives_the_line(tmp_path: Path):
    f = tmp_path / "mount.toml"
    f.write_text("name = 'x'\n[barrel\nwall_mm = 3\n")
    with pytest.raises(InputError) as exc:
        load_mount(f)
    assert exc.value.line == 2
