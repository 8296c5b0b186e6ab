"""Do two run directories hold the same attempts? For optimisations that must not change
what a run records (issue 25): run the same command before and after, then

    .venv/bin/python benchmarks/same_records.py RUN_BEFORE RUN_AFTER

Compared: every record without its wall-clock facts (`deterministic_view`: no timing, no
model stats) and without its prompts' digests; every key frame and every prompt (its
text and images) by content: images by their decoded pixels, so a change of PNG encoding
(compression level, filters) alone does not count as a difference, while any change of
what a model is shown or what happened does. Exit status 0 if the same, 1 otherwise.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from deepphy.chat import Image, TextPart
from deepphy.runs.store import read_prompt, read_records


def pixels(png: bytes) -> np.ndarray:
    return Image(name="x", caption="", png=png).to_array()


def prompt_content(run_dir: Path, task: str, run: int, digest: str) -> list:
    out = []
    for m in read_prompt(run_dir, task, run, digest):
        out.append(m.role)
        for part in m.content:
            if isinstance(part, TextPart):
                out.append(part.text)
            else:
                out += [part.image.name, part.image.caption, pixels(part.image.load()).tobytes()]
    return out


def differences(a: Path, b: Path) -> list[str]:
    key = lambda r: (r.task, r.run, r.attempt)  # noqa: E731
    ra, rb = sorted(read_records(a), key=key), sorted(read_records(b), key=key)
    if [key(r) for r in ra] != [key(r) for r in rb]:
        return [f"different attempts: {len(ra)} vs {len(rb)} records"]
    found = []
    for x, y in zip(ra, rb):
        vx, vy = x.deterministic_view(), y.deterministic_view()
        for view in (vx, vy):
            for step in view["steps"]:
                step.pop("prompt")
        where = f"{x.task} run {x.run} attempt {x.attempt}"
        if vx != vy:
            found.append(f"{where}: records differ")
            continue
        for fx, fy in zip(x.key_frames, y.key_frames):
            if not np.array_equal(pixels((a / fx.path).read_bytes()), pixels((b / fy.path).read_bytes())):
                found.append(f"{where}: key frame {fx.path} differs")
        for sx, sy in zip(x.steps, y.steps):
            if prompt_content(a, x.task, x.run, sx.prompt) != prompt_content(b, y.task, y.run, sy.prompt):
                found.append(f"{where} step {sx.step}: prompts differ")
    return found


def main() -> None:
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    a, b = Path(sys.argv[1]), Path(sys.argv[2])
    found = differences(a, b)
    n = len(read_records(a))
    for line in found[:20]:
        print(line)
    print(f"{n} records compared: " + ("the same (records, key frames' and prompts' pixels and text)"
                                      if not found else f"{len(found)} differences"))
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
