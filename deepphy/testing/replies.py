"""Adversarial model replies: the shapes that once crashed or stalled a parser (huge
integers, megabytes of brackets, keywords followed by endless spaces...). Used by the
parser fuzz test and by benchmarks/parsers.py."""

from __future__ import annotations

from deepphy.envs import ActionSpace
from deepphy.seeding import seeded_rng


def valid_replies(space: ActionSpace, n: int = 20) -> list[str]:
    rng = seeded_rng("fuzz", space.kind)
    return [space.format(space.sample(rng)) for _ in range(n)]


def adversarial_replies(space: ActionSpace) -> dict[str, str]:
    valid = valid_replies(space, 1)[0]
    return {
        "400-digit integers": "".join(c + "0" * 400 if c.isdigit() else c for c in valid),
        "5000-digit integer": '[{"time": 1' + "0" * 5000 + ', "index": 0}] Cell: 1' + "0" * 5000,
        "1 MB of [": "[" * 1_000_000,
        "16k nested brackets": "[" * 16_000 + "]" * 16_000,
        "1 MB of ]": "]" * 1_000_000,
        "keyword then spaces": "cell" + " " * 160 + " radius" + " " * 5000 + valid.split(" ")[0],
        "1 MB of keywords": ("Speed: spot: Cell: Radius: angle= power= cut_pin( push( " * 20_000)[:1_000_000],
        "deep objects": "[" + "{\"a\":" * 10_000 + "1" + "}" * 10_000 + "]",
        "1 MB reply ending in a valid answer": "x" * 1_000_000 + " " + valid,
    }
