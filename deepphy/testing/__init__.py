"""Stand-ins for the outside world, for tests, benchmarks and trying deepphy without keys.

- `model_server`: a local HTTP server that speaks the OpenAI, Anthropic and Gemini wire
  formats and answers with the MOCK policy, with latency and seeded fault injection
  (`python -m deepphy.testing.model_server`).
"""
