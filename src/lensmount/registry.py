"""One idiom for every kind a user or a newcomer extends (BSDF, source, integrator, part kind, CLI verb).

pbrt-v4 creates every object by name from a parameter dictionary (`X::Create(name, parameters)`) and Mitsuba 3
keeps one plugin registry; lensmount does the same. A kind owns one `Registry`; each implementation lives in a
file of its own with a pydantic parameter model (unknown keys forbidden) and registers itself there:

    SOURCES = Registry("source", where="the scene's [source] table")   # in the layer that consumes the kind

    class SunParams(BaseModel):                                         # in the implementation's own file
        model_config = ConfigDict(extra="forbid")
        angular_radius_deg: float = Field(0.266, gt=0, le=5)

    @SOURCES.register("sun", SunParams)
    def build_sun(params: SunParams, **context) -> Sun: ...

    sun = SOURCES.create("sun", {"angular_radius_deg": 0.3}, placement=...)

A user's plug-in registers the same way, from a module the user imports (or names in a design file): the registry
never lists its implementations, so adding one touches only its file and the line that registers it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, ValidationError

from lensmount.errors import InputError
from lensmount.validation import did_you_mean, input_error

T = TypeVar("T")


@dataclass(frozen=True)
class Entry(Generic[T]):
    """One registered implementation: its name, its parameter model and the function that makes it."""

    name: str
    params: type[BaseModel]
    factory: Callable[..., T]
    summary: str


class Registry(Generic[T]):
    """Named implementations of one kind, created from validated parameters.

    Args:
        kind: what the implementations are, in the user's words ("BSDF model", "source", "integrator").
        where: where a user names one (for error messages), e.g. "the scene's [source] type".
    """

    def __init__(self, kind: str, where: str) -> None:
        self.kind = kind
        self.where = where
        self._entries: dict[str, Entry[T]] = {}

    def register(self, name: str, params: type[BaseModel]) -> Callable[[Callable[..., T]], Callable[..., T]]:
        """Decorator: `factory(params_instance, **context) -> T` becomes the implementation called `name`.

        Registering a name twice is a programming error (two plug-ins would shadow each other silently)."""

        def add(factory: Callable[..., T]) -> Callable[..., T]:
            if name in self._entries:
                raise ValueError(f"{self.kind} {name!r} is registered twice")
            doc = (factory.__doc__ or params.__doc__ or "").strip().splitlines()
            self._entries[name] = Entry(name, params, factory, doc[0] if doc else "")
            return factory

        return add

    def names(self) -> tuple[str, ...]:
        return tuple(self._entries)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def entry(self, name: str, *, file: str | None = None, field: str | None = None) -> Entry[T]:
        """The implementation called `name`; InputError listing the valid names (and a did-you-mean) when none is."""
        if name not in self._entries:
            hint = did_you_mean(str(name), self._entries)
            raise InputError(f"unknown {self.kind} {name!r}" + (f" (did you mean {hint!r}?)" if hint else ""),
                             file=file, field=field, valid=f"one of {', '.join(sorted(self._entries))} in {self.where}")
        return self._entries[name]

    def parse(self, name: str, params: Mapping[str, Any] | BaseModel, *, file: str | None = None,
              field: str | None = None) -> BaseModel:
        """`params` checked by `name`'s parameter model: unknown keys, missing keys and ranges as one InputError."""
        model = self.entry(name, file=file, field=field).params
        if isinstance(params, model):
            return params
        try:
            return model.model_validate(dict(params))
        except ValidationError as exc:
            raise input_error(exc, model, file=file, prefix=tuple(field.split(".")) if field else ()) from None

    def create(self, name: str, params: Mapping[str, Any] | BaseModel, *, file: str | None = None,
               field: str | None = None, **context: Any) -> T:
        """The implementation `name` made from `params` (validated first) and the caller's `context`."""
        checked = self.parse(name, params, file=file, field=field)
        return self.entry(name).factory(checked, **context)
