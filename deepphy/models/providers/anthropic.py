"""Anthropic Messages."""

from __future__ import annotations

import math

from deepphy.models.providers.spec import ProviderSpec


def image_tokens(w: int, h: int) -> int:
    """Anthropic: width x height / 750, after resizing the long edge to at most 1568 px.
    Read on 2026-11-23 from docs.anthropic.com/en/docs/build-with-claude/vision
    ("Calculate image costs")."""
    scale = min(1.0, 1568 / max(w, h))
    return math.ceil(w * scale * h * scale / 750)


SPEC = ProviderSpec(
    name="anthropic",
    title="Anthropic Messages",
    client="deepphy.models.clients:AnthropicClient",
    base_url="https://api.anthropic.com/v1",
    max_images=100,  # Anthropic documents 100 images per API request
    image_tokens=image_tokens,
)
