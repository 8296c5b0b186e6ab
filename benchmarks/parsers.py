"""Parse time of adversarial replies (1 MB of brackets, 5000-digit numbers, keywords and
endless spaces...) for every registered action space: the slowest parse per space.

    uv run python benchmarks/parsers.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import time

from deepphy.envs import InvalidAction, specs
from deepphy.testing.replies import adversarial_replies


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="best of N per reply")
    args = ap.parse_args()
    for name, spec in specs().items():
        env_cls = spec.load()
        options = env_cls.Options()
        space = env_cls(options).reset(env_cls.tasks(options)[0]).action_space
        times = {}
        for label, text in adversarial_replies(space).items():
            best = float("inf")
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                try:
                    space.parse(text)
                except InvalidAction:
                    pass
                best = min(best, time.perf_counter() - t0)
            times[label] = best
        label, worst = max(times.items(), key=lambda kv: kv[1])
        print(f"{name:12} slowest {1000 * worst:7.2f} ms ({label}); median {1000 * sorted(times.values())[len(times) // 2]:.2f} ms")


if __name__ == "__main__":
    main()
