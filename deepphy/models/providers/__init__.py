"""The provider registry: every module `deepphy/models/providers/<name>.py` that defines `SPEC`.

Adding a provider = its client class (the wire format) and a module declaring its `SPEC`
(name, client, defaults, image-token rule); nothing else in deepphy names it. Tests and
plug-ins can add one from elsewhere with `register_provider(spec)` (docs/providers.md).
"""

from __future__ import annotations

from deepphy.models.providers.spec import ProviderSpec
from deepphy.registry import Registry


class UnknownProvider(KeyError):
    def __str__(self) -> str:
        return f"unknown provider {self.args[0]!r}; registered: {', '.join(sorted(providers()))}"


_registry: Registry[ProviderSpec] = Registry(ProviderSpec, __name__, __path__, "provider", UnknownProvider)
providers = _registry.all
provider_spec = _registry.get
register_provider = _registry.register
unregister_provider = _registry.unregister

__all__ = ["ProviderSpec", "UnknownProvider", "provider_spec", "providers", "register_provider", "unregister_provider"]
