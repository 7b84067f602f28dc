"""Shared input checks: TOML syntax errors name the line; unknown keys list the keys allowed there."""

import pytest
from pydantic import BaseModel, ConfigDict

from lensmount.errors import InputError
from lensmount.validation import keys_at, parse_toml


class Inner(BaseModel):
    model_config = ConfigDict(extra="forbid")
    width_mm: float = 1.0
    pixels: int = 1


class Outer(BaseModel):
    model_config = ConfigDict(extra="forbid")
    detector: Inner = Inner()
    objects: list[Inner] = []
    finishes: dict[str, Inner] = {}


def test_keys_at_walks_tables_lists_and_dicts():
    assert keys_at(Outer, ("bogus",)) == ["detector", "objects", "finishes"]
    assert keys_at(Outer, ("detector", "bogus")) == ["width_mm", "pixels"]
    assert keys_at(Outer, ("objects", 3, "bogus")) == ["width_mm", "pixels"]
    assert keys_at(Outer, ("finishes", "matte", "bogus")) == ["width_mm", "pixels"]


def test_toml_syntax_error_names_file_and_line():
    with pytest.raises(InputError) as err:
        parse_toml("a = 1\nb = = 2\n", "scene.toml")
    assert err.value.file == "scene.toml" and err.value.line == 2
    assert "not valid TOML" in err.value.paragraph()


TOML = '''description = "x"

[source]
type = "sun"
off_axis_deg = 7.0

[finishes]
edge = { model = "lambertian", reflectance = 0.1 }
"lambert-0.05" = { model = "lambertian", reflectance = 0.05 }

[assign]
"*" = "absorber"
"role:diaphragm-edge" = "edge"

[[objects]]
name = "a"

[[objects]]
name = "b"
finish = "mirror"   # [not a header]
'''


def test_line_of_key_follows_tables_arrays_inline_and_quoted_keys():
    from lensmount.validation import line_of_key

    lines = TOML.splitlines()
    assert line_of_key(TOML, "description") == 1
    assert line_of_key(TOML, "source.off_axis_deg") == 5
    assert line_of_key(TOML, "source.azimuth_deg") == 3           # missing key: its table's header
    assert line_of_key(TOML, "finishes.edge.reflectance") == 8    # inside an inline table
    assert line_of_key(TOML, "finishes.lambert-0.05.reflectance") == 9  # a dot inside a quoted key
    assert line_of_key(TOML, "assign.role:diaphragm-edge") == 13
    assert line_of_key(TOML, "assign.*") == 12
    assert line_of_key(TOML, "objects.1.finish") == 20 and lines[19].startswith("finish")
    assert line_of_key(TOML, "objects.0.finish") == 15            # the first [[objects]] has none: its header
    assert line_of_key(TOML, "detector.width_mm") is None
    assert line_of_key(None, "source") is None


def test_unknown_key_is_reported_before_the_missing_one_it_leaves():
    from pydantic import ValidationError

    from lensmount.validation import input_error

    class Source(BaseModel):
        model_config = ConfigDict(extra="forbid")
        off_axis_deg: float
        azimuth_deg: float = 90.0

    class Scene(BaseModel):
        model_config = ConfigDict(extra="forbid")
        source: Source

    text = "[source]\noff_axis_degree = 7.0\n"
    try:
        Scene.model_validate({"source": {"off_axis_degree": 7.0}})
    except ValidationError as exc:
        err = input_error(exc, Scene, file="s.toml", text=text)
    assert err.field == "source.off_axis_degree" and err.line == 2
    assert err.detail == "unknown key 'off_axis_degree' (did you mean 'off_axis_deg'?)"
    assert err.valid == "off_axis_deg, azimuth_deg"
    try:
        Scene.model_validate({"source": {}})
    except ValidationError as exc:
        err = input_error(exc, Scene, file="s.toml", text="[source]\n")
    assert err.detail == "missing key 'off_axis_deg'" and err.line == 1


def test_did_you_mean_only_suggests_close_words():
    from lensmount.validation import did_you_mean

    assert did_you_mean("black-anodized", ["absorber", "black-anodised", "mirror"]) == "black-anodised"
    assert did_you_mean("zzz", ["absorber", "mirror"]) is None
