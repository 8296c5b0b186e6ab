"""OpenAI Chat Completions: OpenAI, and any compatible server (vLLM, SGLang, ...)."""

from __future__ import annotations

import math

from deepphy.models.providers.spec import ProviderSpec


def image_tokens(w: int, h: int) -> int:
    """OpenAI, detail "high" (GPT-4o / GPT-4.1 family): fit in 2048x2048, then the short
    side to at most 768; 170 tokens per 512-px tile plus 85. Read on 2026-11-23 from
    platform.openai.com/docs/guides/images-vision ("Calculating costs"). Self-hosted
    compatible servers (vLLM, SGLang) count with their own processor: the rule is then an
    estimate."""
    scale = min(1.0, 2048 / max(w, h))
    w, h = w * scale, h * scale
    scale = min(1.0, 768 / min(w, h))
    w, h = w * scale, h * scale
    return 85 + 170 * math.ceil(w / 512) * math.ceil(h / 512)


SPEC = ProviderSpec(
    name="openai",
    title="OpenAI Chat Completions",
    client="deepphy.models.clients:OpenAIChatClient",
    base_url="https://api.openai.com/v1",
    # Compatible servers vary widely (vLLM's limit_mm_per_prompt is set per deployment):
    # a cautious default, to override per model.
    max_images=50,
    image_tokens=image_tokens,
)
