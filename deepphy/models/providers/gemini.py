"""Gemini API generateContent."""

from __future__ import annotations

import math

from deepphy.models.providers.spec import ProviderSpec


def image_tokens(w: int, h: int) -> int:
    """Gemini 2.x: 258 tokens for an image of at most 384x384, else 258 per 768x768 tile.
    Read on 2026-11-23 from ai.google.dev/gemini-api/docs/tokens ("Multimodal tokens")."""
    if w <= 384 and h <= 384:
        return 258
    return 258 * math.ceil(w / 768) * math.ceil(h / 768)


SPEC = ProviderSpec(
    name="gemini",
    title="Gemini API generateContent",
    client="deepphy.models.clients:GeminiClient",
    base_url="https://generativelanguage.googleapis.com/v1beta",
    max_images=3000,  # Gemini accepts thousands
    image_tokens=image_tokens,
)
