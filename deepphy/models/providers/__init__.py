"""The provider registry: every module `deepphy/models/providers/<name>.py` that defines `SPEC`.

Adding a provider = its client class (the wire format) and a module declaring its `SPEC`
(name, client, defaults, image-token rule); nothing else in deepphy names it. Tests and
plug-ins can add one from elsewhere with `register_provider(spec)` (docs/providers.md).
"""

from __future__ import annotations

import importlib
import pkgutil

from deepphy.models.providers.spec import ProviderSpec

_registry: dict[str, ProviderSpec] = {}
_discovered = False


class UnknownProvider(KeyError):
    def __str__(self) -> str:
        return f"unknown provider {self.args[0]!r}; registered: {', '.join(sorted(providers()))}"


def _discover() -> None:
    global _discovered
    if _discovered:
        return
    _discovered = True
    for module in pkgutil.iter_modules(__path__):
        spec = getattr(importlib.import_module(f"{__name__}.{module.name}"), "SPEC", None)
        if isinstance(spec, ProviderSpec):
            _registry.setdefault(spec.name, spec)


def providers() -> dict[str, ProviderSpec]:
    """Every registered provider, by name (the modules' order, then registrations)."""
    _discover()
    return dict(_registry)


def provider_spec(name: str) -> ProviderSpec:
    _discover()
    try:
        return _registry[name]
    except KeyError:
        raise UnknownProvider(name) from None


def register_provider(spec: ProviderSpec) -> ProviderSpec:
    """Add a provider that does not live in deepphy/models/providers/ (a test's, a plug-in's)."""
    _discover()
    if spec.name in _registry and _registry[spec.name] != spec:
        raise ValueError(f"another provider is already registered as {spec.name!r}")
    _registry[spec.name] = spec
    return spec


def unregister_provider(name: str) -> None:
    _registry.pop(name, None)


__all__ = ["ProviderSpec", "UnknownProvider", "provider_spec", "providers", "register_provider", "unregister_provider"]
