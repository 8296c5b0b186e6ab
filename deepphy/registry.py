"""A registry of declarations found in a package: every module (or subpackage) of it that
defines `SPEC` of the registry's type, plus what tests and plug-ins register from elsewhere.
The environments (`deepphy.envs`) and the model providers (`deepphy.models.providers`) are
two of these; adding one is adding its module, and nothing else names it."""

from __future__ import annotations

import importlib
import pkgutil
from typing import Callable, Generic, Iterable, TypeVar

S = TypeVar("S")


class Registry(Generic[S]):
    """Specs of type `kind` by their `.name`, found on first use in the modules of `package`
    (`path`: its __path__; `packages_only`: only its subpackages), then registered ones.
    `unknown(name)` is the error a lookup of an unregistered name raises."""

    def __init__(self, kind: type[S], package: str, path: Iterable[str], noun: str,
                 unknown: Callable[[str], Exception], packages_only: bool = False) -> None:
        self.kind, self.package, self.path, self.noun = kind, package, list(path), noun
        self.unknown, self.packages_only = unknown, packages_only
        self._specs: dict[str, S] = {}
        self._discovered = False

    def _discover(self) -> None:
        if self._discovered:
            return
        self._discovered = True
        for module in pkgutil.iter_modules(self.path):
            if self.packages_only and not module.ispkg:
                continue
            spec = getattr(importlib.import_module(f"{self.package}.{module.name}"), "SPEC", None)
            if isinstance(spec, self.kind):
                self._specs.setdefault(spec.name, spec)  # type: ignore[attr-defined]

    def all(self) -> dict[str, S]:
        """Every registered spec, by name (the modules' order, then registrations)."""
        self._discover()
        return dict(self._specs)

    def get(self, name: str) -> S:
        self._discover()
        try:
            return self._specs[name]
        except KeyError:
            raise self.unknown(name) from None

    def register(self, spec: S) -> S:
        """Add a spec that does not live in the package (a test's, a plug-in's)."""
        self._discover()
        name = spec.name  # type: ignore[attr-defined]
        if name in self._specs and self._specs[name] != spec:
            raise ValueError(f"another {self.noun} is already registered as {name!r}")
        self._specs[name] = spec
        return spec

    def unregister(self, name: str) -> None:
        self._specs.pop(name, None)
