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

The registry never lists its implementations, so adding one touches only its file and the line that registers it.
Before its first lookup a registry imports every module of its `implementations` package (the built-ins: a new
file there is found) and every plug-in installed under the entry-point group `lensmount.plugins`: a user's package
declares

    [project.entry-points."lensmount.plugins"]
    velvet = "my_lab.velvet"        # a module that registers on import, like a built-in

so the plug-in is there for every command and in every worker process, without lensmount naming it.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, ValidationError

from lensmount.errors import InputError
from lensmount.validation import did_you_mean, input_error

T = TypeVar("T")

PLUGIN_GROUP = "lensmount.plugins"
_plugins_loaded = False


def load_plugins() -> None:
    """Import every module installed under the entry-point group `lensmount.plugins` (once per process)."""
    global _plugins_loaded
    if _plugins_loaded:
        return
    _plugins_loaded = True
    for point in entry_points(group=PLUGIN_GROUP):
        try:
            point.load()
        except Exception as exc:  # the user's code: report it as their input
            raise InputError(f"the plug-in {point.name!r} ({point.value}) failed to load: {exc!r}",
                             field=f'[project.entry-points."{PLUGIN_GROUP}"] {point.name}',
                             valid="a module that imports and registers its implementation") from None


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
        implementations: the package whose modules hold the built-in implementations (each registers itself
            when imported); every one of its modules is imported before the first lookup.
    """

    def __init__(self, kind: str, where: str, implementations: str | None = None) -> None:
        self.kind = kind
        self.where = where
        self.implementations = implementations
        self._entries: dict[str, Entry[T]] = {}
        self._complete = False

    def _all(self) -> dict[str, Entry[T]]:
        """The entries, after the built-ins and the installed plug-ins have registered."""
        if not self._complete:
            self._complete = True
            if self.implementations:
                package = importlib.import_module(self.implementations)
                for module in pkgutil.iter_modules(package.__path__):
                    if not module.ispkg and not module.name.startswith("_"):
                        importlib.import_module(f"{self.implementations}.{module.name}")
            load_plugins()
        return self._entries

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
        return tuple(self._all())

    def __contains__(self, name: object) -> bool:
        return name in self._all()

    def entry(self, name: str, *, file: str | None = None, field: str | None = None) -> Entry[T]:
        """The implementation called `name`; InputError listing the valid names (and a did-you-mean) when none is."""
        if not isinstance(name, str) or name not in self._all():  # a list or number from a file is no name
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
            keys = ", ".join(model.model_fields) or "none"
            raise input_error(exc, model, file=file, prefix=tuple(field.split(".")) if field else (),
                              valid=f"the parameters of the {self.kind} {name!r}: {keys}") from None

    def create(self, name: str, params: Mapping[str, Any] | BaseModel, *, file: str | None = None,
               field: str | None = None, **context: Any) -> T:
        """The implementation `name` made from `params` (validated first) and the caller's `context`."""
        checked = self.parse(name, params, file=file, field=field)
        return self.entry(name).factory(checked, **context)
