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
