"""The run's actors: each a plain class (`...Impl`) that Ray runs as an actor, or a run in
this process (`deepphy.in_process`) calls directly."""

from __future__ import annotations

from typing import Any


class remote_class:  # noqa: N801 - stands for the actor class it makes
    """`ray.remote(impl)`, made once, by the first `get()`: importing an actor's module
    imports no Ray."""

    def __init__(self, impl: type) -> None:
        self.impl, self._made = impl, None

    def get(self) -> Any:
        if self._made is None:
            import ray  # at first use: importing an actor's module imports no Ray

            self._made = ray.remote(self.impl)
        return self._made

    def options(self, **options: Any) -> Any:
        return self.get().options(**options)
