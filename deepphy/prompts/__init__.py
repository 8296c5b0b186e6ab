"""Prompts: the words shown to a model. The shared builder lives here; each environment's
words live in its own package (deepphy/envs/<name>/prompt.py, loaded via its EnvSpec)."""

from __future__ import annotations

from deepphy.chat import ImagePart, Message, PromptFormat, TextPart
from deepphy.prompts.base import (
    OUTCOMES,
    EnvPrompt,
    PastAttempt,
    PastStep,
    Reply,
    build_messages,
    image_digest,
    mock_reply,
    prompt_as_json,
    prompt_digest,
    split_reply,
)

__all__ = [
    "OUTCOMES", "Reply", "EnvPrompt", "ImagePart", "Message", "PastAttempt", "PastStep", "PromptFormat", "TextPart",
    "build_messages", "image_digest", "mock_reply", "prompt_as_json", "prompt_digest", "split_reply",
]
