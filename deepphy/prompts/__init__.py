"""Prompts: the words shown to a model. One module per environment, plus the shared builder."""

from __future__ import annotations

import importlib

from deepphy.prompts.base import (
    EnvPrompt,
    ImagePart,
    Message,
    PastAttempt,
    PastStep,
    PromptFormat,
    TextPart,
    build_messages,
    mock_reply,
    split_reply,
)

# env name -> "module:Class"
PROMPTS: dict[str, str] = {
    "iphyre": "deepphy.prompts.iphyre:IPhyrePrompt",
    "kinetix": "deepphy.prompts.kinetix:KinetixPrompt",
    "pooltool": "deepphy.prompts.pooltool:PooltoolPrompt",
    "phyre": "deepphy.prompts.phyre:PhyrePrompt",
}


def get_prompt(env: str) -> EnvPrompt:
    module, cls = PROMPTS[env].split(":")
    return getattr(importlib.import_module(module), cls)()


__all__ = [
    "EnvPrompt", "ImagePart", "Message", "PROMPTS", "PastAttempt", "PastStep", "PromptFormat",
    "TextPart", "build_messages", "get_prompt", "mock_reply", "split_reply",
]
