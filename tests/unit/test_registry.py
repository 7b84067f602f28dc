"""The one registry idiom: create by name from checked parameters; unknown names and keys are one InputError."""

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
