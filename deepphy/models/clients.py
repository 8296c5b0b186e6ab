"""Request and response formats of the built-in providers' APIs (each declared in
deepphy/models/providers/<name>.py).

- OpenAI Chat Completions (POST {base}/chat/completions; OpenAI, vLLM, SGLang, ...):
  system text as a system message, user content as parts `{"type": "text"}` /
  `{"type": "image_url", "image_url": {"url": "data:image/png;base64,..."}}`,
  `temperature`, `max_tokens` (or `max_completion_tokens`), `seed`; bearer key.
- Anthropic Messages (POST {base}/messages): `system` as a top-level string, content
  blocks `{"type": "text"}` / `{"type": "image", "source": {"type": "base64",
  "media_type": "image/png", "data": ...}}`, `max_tokens` required, `temperature` only
  before API version 2026-10-21 (which removed the sampling parameters: any of them is a
  400); headers `x-api-key` and `anthropic-version`.
- Gemini generateContent (POST {base}/models/{model}:generateContent): `contents` of
  `{"role": "user"|"model", "parts": [{"text"} | {"inlineData": {"mimeType", "data"}}]}`,
  `systemInstruction`, `generationConfig` {temperature, maxOutputTokens, seed}; header
  `x-goog-api-key` (never a `?key=` query, which would put the key in URLs and logs).
"""

from __future__ import annotations

from typing import Any

from deepphy.chat import ImagePart, Message, TextPart
from deepphy.models.base import ModelRequest
from deepphy.models.http import EmptyReply, HTTPModelClient, request_seed
from deepphy.models.wire import ANTHROPIC_NO_SAMPLING_FROM, png_b64


def _system_text(messages: list[Message], provider: str) -> str:
    system = [m for m in messages if m.role == "system"]
    if any(m.images for m in system):  # every provider takes system text only
        raise ValueError(f"{provider}: a system message cannot carry images")
    return "\n\n".join(m.text for m in system)


class OpenAIChatClient(HTTPModelClient):
    def url(self) -> str:
        return f"{self.config.resolved_base_url}/chat/completions"

    def auth_headers(self, key: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {key}"}

    @staticmethod
    def message(m: Message) -> dict[str, Any]:
        if m.role != "user":
            if m.images:  # system and assistant content is text (or refusal) parts only
                raise ValueError(f"openai: a {m.role} message cannot carry images")
            return {"role": m.role, "content": m.text}
        content: list[dict[str, Any]] = []
        for p in m.content:
            if isinstance(p, TextPart):
                content.append({"type": "text", "text": p.text})
            else:
                content.append({"type": "image_url", "image_url": {"url": f"data:image/png;base64,{png_b64(p.image.load())}"}})
        return {"role": m.role, "content": content}

    def build_body(self, request: ModelRequest, messages: list[Message], max_tokens: int) -> dict[str, Any]:
        cfg = self.config
        body: dict[str, Any] = {"model": cfg.model, "messages": [self.message(m) for m in messages]}
        body[cfg.max_tokens_param] = max_tokens
        if cfg.send_temperature:
            body["temperature"] = request.temperature
        if cfg.send_seed:
            body["seed"] = request_seed(request.context)
        return body

    def parse(self, data: Any) -> tuple[str, int | None, int | None]:
        choices = data["choices"]
        if not choices:
            raise EmptyReply("no choices")
        content = choices[0]["message"].get("content")
        if isinstance(content, list):  # some compatible servers return parts
            content = "".join(p.get("text", "") for p in content if isinstance(p, dict))
        usage = data.get("usage") or {}
        return content or "", usage.get("prompt_tokens"), usage.get("completion_tokens")


class AnthropicClient(HTTPModelClient):
    def url(self) -> str:
        return f"{self.config.resolved_base_url}/messages"

    def auth_headers(self, key: str) -> dict[str, str]:
        return {"x-api-key": key}

    def static_headers(self) -> dict[str, str]:
        return {"anthropic-version": self.config.anthropic_version}

    @staticmethod
    def block(p: TextPart | ImagePart) -> dict[str, Any]:
        if isinstance(p, TextPart):
            return {"type": "text", "text": p.text}
        return {"type": "image", "source": {"type": "base64", "media_type": "image/png", "data": png_b64(p.image.load())}}

    def build_body(self, request: ModelRequest, messages: list[Message], max_tokens: int) -> dict[str, Any]:
        cfg = self.config
        body: dict[str, Any] = {
            "model": cfg.model,
            "max_tokens": max_tokens,
            "messages": [
                {"role": m.role, "content": [self.block(p) for p in m.content]} for m in messages if m.role != "system"
            ],
        }
        system = _system_text(messages, "anthropic")
        if system:
            body["system"] = system
        if cfg.send_temperature and cfg.anthropic_version < ANTHROPIC_NO_SAMPLING_FROM:
            body["temperature"] = request.temperature
        return body  # the Messages API takes no seed

    def parse(self, data: Any) -> tuple[str, int | None, int | None]:
        if data.get("type") == "error":
            raise KeyError("error")
        content = data["content"]
        if not content:
            raise EmptyReply(f"no content (stop_reason {data.get('stop_reason')})")
        text = "".join(b.get("text", "") for b in content if b.get("type") == "text")
        usage = data.get("usage") or {}
        tin = usage.get("input_tokens")
        if tin is not None:  # cached prompt tokens are billed too (at other rates; counted here as input)
            tin += (usage.get("cache_creation_input_tokens") or 0) + (usage.get("cache_read_input_tokens") or 0)
        return text, tin, usage.get("output_tokens")


class GeminiClient(HTTPModelClient):
    def url(self) -> str:
        return f"{self.config.resolved_base_url}/models/{self.config.model}:generateContent"

    def auth_headers(self, key: str) -> dict[str, str]:
        return {"x-goog-api-key": key}

    @staticmethod
    def part(p: TextPart | ImagePart) -> dict[str, Any]:
        if isinstance(p, TextPart):
            return {"text": p.text}
        return {"inlineData": {"mimeType": "image/png", "data": png_b64(p.image.load())}}

    def build_body(self, request: ModelRequest, messages: list[Message], max_tokens: int) -> dict[str, Any]:
        cfg = self.config
        body: dict[str, Any] = {
            "contents": [
                {"role": "model" if m.role == "assistant" else "user", "parts": [self.part(p) for p in m.content]}
                for m in messages
                if m.role != "system"
            ]
        }
        system = _system_text(messages, "gemini")
        if system:
            body["systemInstruction"] = {"parts": [{"text": system}]}
        gen: dict[str, Any] = {"maxOutputTokens": max_tokens}
        if cfg.send_temperature:
            gen["temperature"] = request.temperature
        if cfg.send_seed:
            gen["seed"] = request_seed(request.context)
        body["generationConfig"] = gen
        return body

    def parse(self, data: Any) -> tuple[str, int | None, int | None]:
        candidates = data.get("candidates")
        if not candidates:
            reason = (data.get("promptFeedback") or {}).get("blockReason")
            raise EmptyReply("no candidates" + (f" (blocked: {reason})" if reason else ""))
        parts = (candidates[0].get("content") or {}).get("parts") or []
        text = "".join(p.get("text", "") for p in parts if not p.get("thought"))
        usage = data.get("usageMetadata") or {}
        tout = usage.get("candidatesTokenCount")
        if tout is not None or usage.get("thoughtsTokenCount"):
            tout = (tout or 0) + (usage.get("thoughtsTokenCount") or 0)  # thinking is billed as output
        return text, usage.get("promptTokenCount"), tout
