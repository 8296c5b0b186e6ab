"""`deepphy export`: the decisions of run directories as a Parquet dataset.

One row per decision (step of an attempt) with its prompt (messages, images by relative
path), raw reply, parsed action, validity and outcome; the key frames are copied next to
it; README.md is the dataset card. Loadable with `pandas.read_parquet(DIR / DATA_FILE)`
and `datasets.load_dataset("parquet", data_files=...)`, or `datasets.load_dataset(DIR)`.
The chat layout (`--layout chat`, CHAT_FILE) is the same decisions for supervised
fine-tuning: the conversation as the model saw it, then its reply, images by path.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import pyarrow as pa
import pyarrow.parquet as pq

from deepphy.envs import specs
from deepphy.envs.base import Planning
from deepphy.plan import plan
from deepphy.runs.records import AttemptRecord, KeyFrame
from deepphy.prompts.base import CURRENT_OBSERVATION
from deepphy.runs.store import (
    FRAMES, OLD_IMAGE_PLACEHOLDER, RunDirError, check_confined, check_records, episode_prompts, inside, read_config,
    read_image, read_records, stored_image, stored_prompt_json,
)

DATA_FILE = "data/decisions.parquet"
IMAGES = "images"
MARKER = "<!-- deepphy export -->"  # identifies a directory an earlier export wrote
BY_DIGEST = f"{IMAGES}/sha256"  # prompt images, named by the sha256 of their bytes, as in the run directory

PART = pa.struct([
    ("type", pa.string()),  # "text" or "image"
    ("text", pa.string()),  # the text (type text)
    ("image", pa.string()),  # relative path of the stored image, or null if it was not stored
    ("name", pa.string()),  # the image's name in the prompt
    ("caption", pa.string()),
])
MESSAGE = pa.struct([("role", pa.string()), ("content", pa.list_(PART))])

# (name, type, meaning): the schema and the dataset card's field table.
FIELDS: list[tuple[str, pa.DataType, str]] = [
    ("source", pa.string(), "which run directory the row comes from (see Sources)"),
    ("env", pa.string(), "environment"),
    ("task", pa.string(), "task id"),
    ("group", pa.string(), "task group (e.g. a size or a split); empty if none"),
    ("run", pa.int32(), "repetition of the task (0-based)"),
    ("attempt", pa.int32(), "attempt number (1-based); every attempt starts from the same initial state"),
    ("step", pa.int32(), "decision number within the attempt (1-based)"),
    ("model", pa.string(), "model name"),
    ("format", pa.string(), "prompt format: vla (action only) or wm (prediction, then action)"),
    ("seed", pa.int64(), "the run's seed"),
    ("prompt_digest", pa.string(), "content hash of the prompt (a line of prompts/<task>/r<run>.jsonl in the run "
                                   "directory; prompts/<digest>.json in runs before those logs)"),
    ("prompt", pa.list_(MESSAGE), "the chat messages; image parts carry a relative path when the image is stored"),
    ("images", pa.list_(pa.string()), "relative paths of the prompt's stored images, in order"),
    ("observation_images", pa.list_(pa.string()),
     "relative paths of the current observation's images (the decision's input scene), in order"),
    ("history_images", pa.list_(pa.string()),
     "relative paths of the history images in the prompt (earlier attempts and decisions), in order"),
    ("images_not_stored", pa.int32(), "images the model was shown that the run directory does not keep "
                                      "(runs made before deepphy stored every prompt image)"),
    ("raw_output", pa.string(), "the model's reply, verbatim"),
    ("prediction", pa.string(), "the WM prediction (null for VLA)"),
    ("action", pa.string(), "the parsed action as JSON (null if the reply did not parse)"),
    ("action_text", pa.string(), "the action in canonical syntax (null if the reply did not parse)"),
    ("valid", pa.bool_(), "whether the decision was a valid action"),
    ("invalid_reason", pa.string(), "why it was invalid (null if valid)"),
    ("feedback", pa.string(), "what the decision did, in words"),
    ("info", pa.string(), "environment facts about the decision, as JSON"),
    ("key_frames", pa.list_(pa.string()), "relative paths of the key frames after this decision"),
    ("key_frame_captions", pa.list_(pa.string()), "their captions"),
    ("final_step", pa.bool_(), "whether this decision ended the attempt"),
    ("success", pa.bool_(), "whether the attempt solved the task"),
    ("attempt_invalid_reason", pa.string(), "set when the attempt ended on an invalid action"),
    ("outcome", pa.string(), "the attempt's outcome in words, as shown to the model in later attempts"),
    ("stars", pa.int32(), "stars of the attempt (games only, else null)"),
    ("score", pa.float64(), "score of the attempt, if the environment has one"),
    ("attempt_input_tokens", pa.int64(), "input tokens of the whole attempt"),
    ("attempt_output_tokens", pa.int64(), "output tokens of the whole attempt"),
    ("attempt_cost_usd", pa.float64(), "model cost of the whole attempt"),
    ("attempt_images_dropped", pa.int32(), "images of the attempt's requests left out to meet the endpoint's "
                                           "per-request image limit (each sent as a one-line text in its place)"),
]
SCHEMA = pa.schema([(name, type_) for name, type_, _ in FIELDS])

# The chat layout: a part is a text or an image (by path), as the model's API received it
# (an image's name and caption are not sent with it; the prompt's text says what it shows).
CHAT_FILE = "data/chat.parquet"
CHAT_PART = pa.struct([("type", pa.string()), ("text", pa.string()), ("image", pa.string())])
CHAT_MESSAGE = pa.struct([("role", pa.string()), ("content", pa.list_(CHAT_PART))])
_FIELD = {f[0]: f for f in FIELDS}
CHAT_FIELDS: list[tuple[str, pa.DataType, str]] = [
    *(_FIELD[name] for name in ("source", "env", "task", "group", "run", "attempt", "step", "model", "format",
                                "seed", "prompt_digest")),
    ("messages", pa.list_(CHAT_MESSAGE),
     "the conversation as the model saw it (system, user and earlier turns, in order), then the model's reply as "
     "the last message (role assistant); a part is {type: text, text} or {type: image, image: relative path}"),
    ("images", pa.list_(pa.string()), "relative paths of the conversation's images, in the order of its image parts"),
    *(_FIELD[name] for name in ("observation_images", "history_images", "images_not_stored", "action_text", "valid",
                                "invalid_reason", "final_step", "success", "outcome", "stars", "score",
                                "attempt_images_dropped")),
]
CHAT_SCHEMA = pa.schema([(name, type_) for name, type_, _ in CHAT_FIELDS])
LAYOUTS = {"decisions": (DATA_FILE, SCHEMA, FIELDS), "chat": (CHAT_FILE, CHAT_SCHEMA, CHAT_FIELDS)}
DEFAULT_LAYOUT = "decisions"  # every field of each decision; "chat" is the fine-tuning view of the same


@dataclass
class ExportSummary:
    out: Path
    rows: int
    runs: int
    images: int


class _Images:
    """Copies a run directory's frames into the dataset once each; returns relative paths."""

    def __init__(self, run_dir: Path, staging: Path, source: str) -> None:
        self.run_dir, self.staging, self.source = run_dir, staging, source
        self.copied: dict[str, str | None] = {}

    def add(self, rel: str, whose: str) -> str | None:
        """The dataset path of the run directory's file `rel` (copied), or None if absent.
        `whose`: the record or prompt that names it (for the error if it leads out)."""
        if rel not in self.copied:
            src = inside(self.run_dir, rel)
            if src is None:
                raise RunDirError(f"{self.run_dir}: {rel}, named by {whose}, leads out of the run directory; "
                                  "refusing to read it")
            if not src.is_file():
                self.copied[rel] = None
            else:
                dest = Path(IMAGES) / self.source / Path(rel).relative_to("frames")
                (self.staging / dest).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(src, self.staging / dest)
                self.copied[rel] = dest.as_posix()
        return self.copied[rel]

    def add_stored(self, digest: str) -> str | None:
        """The dataset path of the run directory's images/<digest>.png (copied once, also
        across run directories: the same image is one file), or None if absent. RunDirError
        if it is damaged (see `read_image`)."""
        key = f"sha256:{digest}"
        if key not in self.copied:
            dest = f"{BY_DIGEST}/{digest}.png"
            if (self.staging / dest).exists():  # from another run directory: the same bytes, checked then
                self.copied[key] = dest
            else:
                png = read_image(self.run_dir, digest)
                if png is not None:
                    (self.staging / dest).parent.mkdir(parents=True, exist_ok=True)
                    (self.staging / dest).write_bytes(png)
                self.copied[key] = None if png is None else dest
        return self.copied[key]


def _frames_of_step(record: AttemptRecord, step: int, last: bool) -> list[KeyFrame]:
    """Key frames are named r<run>_a<attempt>_s<step>_<name>.png; frames that carry no
    step go with the attempt's last decision."""
    tag = f"_a{record.attempt}_s{step}_"
    mine = [f for f in record.key_frames if tag in f.path.rsplit("/", 1)[-1]]
    if last:
        tagged = {f.path for s in record.steps for f in record.key_frames
                  if f"_a{record.attempt}_s{s.step}_" in f.path.rsplit("/", 1)[-1]}
        mine += [f for f in record.key_frames if f.path not in tagged]
    return mine


@dataclass
class _Prompt:
    messages: list[dict[str, Any]]
    images: list[str]  # stored images, in order
    observation: list[str]  # those after the current observation's heading
    history: list[str]  # those before it
    missing: int


def _prompt(run_dir: Path, task: str, run: int, digest: str, logged: dict[str, list], images: _Images,
            cache: dict) -> _Prompt:
    """Prompt `digest` of episode (task, run), whose log is `logged` (see episode_prompts);
    `cache` holds the prompts made so far, by digest (the same prompt in two episodes is one)."""
    if digest not in cache:
        messages = stored_prompt_json(run_dir, task, run, digest, logged)
        found = _Prompt([], [], [], [], 0)
        current = False  # past the current observation's heading
        for m in messages:
            parts = []
            for part in m["content"]:
                ref = stored_image(part)
                old = OLD_IMAGE_PLACEHOLDER.match(part) if ref is None else None
                if ref is None and old is None:
                    parts.append({"type": "text", "text": part, "image": None, "name": None, "caption": None})
                    current = current or part == CURRENT_OBSERVATION
                    continue
                if ref is not None:
                    image_digest, name, caption = ref
                    path = images.add_stored(image_digest)
                else:  # a run from before images/: only history key frames were kept, under frames/
                    name, caption = old.groups()
                    path = (images.add(f"{FRAMES}/{task}/{name}", f"prompt {digest}")
                            if "/" not in name and name not in ("", ".", "..") else None)
                parts.append({"type": "image", "text": None, "image": path, "name": name, "caption": caption})
                if path:
                    found.images.append(path)
                    (found.observation if current else found.history).append(path)
                else:
                    found.missing += 1
            found.messages.append({"role": m["role"], "content": parts})
        cache[digest] = found
    return cache[digest]


def rows_of(run_dir: Path, source: str, staging: Path, layout: str = DEFAULT_LAYOUT) -> tuple[list[dict[str, Any]], int]:
    """The rows of one run directory in `layout` (copying the images they name into
    `staging`) and the image count."""
    check_confined(run_dir)  # images/ or frames/ linked out of the run: refused (read, they would be empty)
    images = _Images(run_dir, staging, source)
    prompts: dict[str, Any] = {}
    rows = []
    records = read_records(run_dir)
    check_records(run_dir, records, plan(read_config(run_dir)).k_max, frames=False)  # no duplicated attempts
    records.sort(key=lambda r: (r.task, r.run, r.attempt))
    episode: tuple[str, int] | None = None
    for r in records:
        if episode != (r.task, r.run):  # each episode's prompt log read once
            episode, logged = (r.task, r.run), episode_prompts(run_dir, r.task, r.run)
        for i, s in enumerate(r.steps):
            last = i == len(r.steps) - 1
            prompt = _prompt(run_dir, r.task, r.run, s.prompt, logged, images, prompts)
            frames = _frames_of_step(r, s.step, last) if layout == "decisions" else []  # chat: inputs only
            usage = r.model_stats.usage
            row = {
                "source": source, "env": r.env, "task": r.task, "group": r.group, "run": r.run,
                "attempt": r.attempt, "step": s.step, "model": r.model, "format": r.format, "seed": r.seed,
                "prompt_digest": s.prompt, "prompt": prompt.messages, "images": prompt.images,
                "observation_images": prompt.observation, "history_images": prompt.history,
                "images_not_stored": prompt.missing,
                "raw_output": s.raw_output, "prediction": s.prediction,
                "action": None if s.action is None else json.dumps(s.action, sort_keys=True),
                "action_text": s.action_text, "valid": s.invalid_reason is None, "invalid_reason": s.invalid_reason,
                "feedback": s.feedback, "info": json.dumps(s.info, sort_keys=True),
                "key_frames": [images.add(f.path, f"the record of task {r.task} run {r.run} attempt {r.attempt}")
                               for f in frames], "key_frame_captions": [f.caption for f in frames],
                "final_step": last, "success": r.success, "attempt_invalid_reason": r.invalid_reason,
                "outcome": r.feedback, "stars": r.stars, "score": r.score,
                "attempt_input_tokens": usage.input_tokens, "attempt_output_tokens": usage.output_tokens,
                "attempt_cost_usd": usage.cost_usd, "attempt_images_dropped": r.model_stats.images_dropped,
            }
            rows.append(chat_row(row) if layout == "chat" else row)
    return rows, sum(1 for p in images.copied.values() if p)


def chat_row(row: dict[str, Any]) -> dict[str, Any]:
    """A decision row in the chat layout: its prompt's messages with image parts by path,
    then the reply. An image the run did not store (runs from before images/) stays a text
    part saying so, counted in `images_not_stored`."""
    messages = []
    for m in row["prompt"]:
        content = []
        for p in m["content"]:
            if p["type"] == "text":
                content.append({"type": "text", "text": p["text"], "image": None})
            elif p["image"] is not None:
                content.append({"type": "image", "text": None, "image": p["image"]})
            else:
                content.append({"type": "text", "text": f"<image not stored: {p['caption']}>", "image": None})
        messages.append({"role": m["role"], "content": content})
    messages.append({"role": "assistant", "content": [{"type": "text", "text": row["raw_output"], "image": None}]})
    return {**{k: row[k] for k in CHAT_SCHEMA.names if k != "messages"}, "messages": messages}


def _source_names(run_dirs: Sequence[Path]) -> list[str]:
    names: list[str] = []
    for d in run_dirs:
        base = re.sub(r"[^A-Za-z0-9._-]", "_", d.name) or "run"
        name, n = base, 2
        while name in names:
            name, n = f"{base}-{n}", n + 1
        names.append(name)
    return names


def export(run_dirs: Sequence[str | Path], out: str | Path, layout: str = DEFAULT_LAYOUT) -> ExportSummary:
    """Write the dataset to `out` (a new or empty directory, or an earlier export, which is
    replaced only once the new one is complete), in `layout` (see LAYOUTS)."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r}; one of {', '.join(LAYOUTS)}")
    data_file, schema, _ = LAYOUTS[layout]
    out = Path(out)
    dirs = [Path(d).resolve() for d in run_dirs]
    if len(set(dirs)) != len(dirs):
        raise RunDirError("the same run directory is given twice")
    configs = [read_config(d) for d in dirs]  # a clear error before anything is written
    if out.exists() and any(out.iterdir()) and not _is_export(out):
        raise RunDirError(f"{out} is not empty and not an earlier export; choose a new --out")
    staging = out.with_name(f".{out.name}.partial-{os.getpid()}")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    try:
        rows: list[dict[str, Any]] = []
        sources = []
        for d, name, config in zip(dirs, _source_names(dirs), configs):
            mine, _ = rows_of(d, name, staging, layout)
            rows += mine
            sources.append((name, config, len(mine)))
        n_images = sum(1 for _ in (staging / IMAGES).rglob("*.png"))  # an image shared by runs is one file
        (staging / data_file).parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.Table.from_pylist(rows, schema=schema), staging / data_file, compression="zstd")
        (staging / "README.md").write_text(dataset_card(sources, len(rows), n_images, layout))
        if out.exists():
            old = out.with_name(f".{out.name}.old-{os.getpid()}")
            out.rename(old)
            staging.rename(out)
            shutil.rmtree(old)
        else:
            staging.rename(out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return ExportSummary(out=out, rows=len(rows), runs=len(dirs), images=n_images)


def _is_export(path: Path) -> bool:
    card = path / "README.md"
    return card.is_file() and MARKER in card.read_text(errors="replace")


def dataset_card(sources: list[tuple[str, Any, int]], rows: int, images: int, layout: str = DEFAULT_LAYOUT) -> str:
    data_file, _, fields = LAYOUTS[layout]
    source_lines = "\n".join(
        f"| `{name}` | {c.env} | {c.model} | {c.format.value} | {c.runs} | {c.seed} | "
        f"`{json.dumps(c.env_options, sort_keys=True)}` | {n} |"
        for name, c, n in sources
    )
    field_lines = "\n".join(f"| `{name}` | `{type_}` | {meaning} |" for name, type_, meaning in fields)
    by_planning = {p: ", ".join(s.title for s in specs().values() if s.planning is p) for p in Planning}
    in_advance, on_the_fly = by_planning[Planning.IN_ADVANCE], by_planning[Planning.ON_THE_FLY]
    key_frames = "" if layout == "chat" else f""" Key frames (what happened after a
decision) are `{IMAGES}/<source>/<task>/<file>.png`, referenced from `key_frames`."""
    if layout == "chat":
        layout_text = """Layout `chat` (`deepphy export --layout chat`), for supervised fine-tuning: each row's
`messages` is the conversation as the model was sent it (the stored
prompt: system and user messages, text and images in order), followed by the model's
reply as an `assistant` message. An image part names its file in `image` (a path
relative to this directory); `images` lists them in the order of the image parts (the
layout of TRL's vision SFT: one image per image part, in order). Choose rows to train on
with the outcome columns: e.g. `success` (the attempt solved the task), `valid`, `stars`.
Where the endpoint's per-request image limit dropped older images
(`attempt_images_dropped` > 0), the request held a one-line text in place of each; the
conversation here keeps the images."""
        loading = f"""```python
import datasets
from PIL import Image
ds = datasets.load_dataset("parquet", data_files="{data_file}")["train"]
row = ds[0]
images = [Image.open(path) for path in row["images"]]  # paths relative to this directory
for m in row["messages"]:
    print(m["role"], [p["text"] if p["type"] == "text" else "<image " + p["image"] + ">" for p in m["content"]])
```"""
    else:
        layout_text = """Layout `decisions` (the default): every field of a decision and its attempt; the
prompt's image parts keep their names and captions. `deepphy export --layout chat`
writes the same decisions as conversations for supervised fine-tuning."""
        loading = f"""```python
import pandas as pd
df = pd.read_parquet("{data_file}")

import datasets
ds = datasets.load_dataset("parquet", data_files="{data_file}")["train"]
```"""
    return f"""---
configs:
- config_name: default
  data_files: {data_file}
---
{MARKER}
# deepphy trajectories

Decisions of vision-language models (or of the MOCK random baseline) acting in
interactive physics environments, exported by `deepphy export` from deepphy run
directories. One row per decision: {rows} rows, {images} image files.

An attempt is one try at a task from its initial state; before each attempt the model
sees its earlier failed attempts. In-advance environments ({in_advance}) take one
decision per attempt; on-the-fly ones ({on_the_fly}) several. `success`,
`outcome`, `stars` and the `attempt_*` columns describe the whole attempt and repeat on
each of its decisions.

{layout_text}

## Sources

| source | env | model | format | runs | seed | env options | rows |
|---|---|---|---|---|---|---|---|
{source_lines}

## Fields

| field | type | meaning |
|---|---|---|
{field_lines}

## Images

Every image a model was shown is `{BY_DIGEST}/<sha256>.png` (the sha256 of its PNG bytes:
one file however many prompts, attempts and runs showed it), referenced by relative path
from the conversation's image parts and listed in `images`, `observation_images` (the
scene the decision was made from) and `history_images`.{key_frames}
Runs made before deepphy stored every prompt image kept only the key frames: there the
current observation is not in the dataset ({"its prompt part has `image = null`, with its name and caption"
if layout == "decisions" else "its part is the text `<image not stored: CAPTION>`"}), counted in
`images_not_stored`.

## Loading

{loading}
"""
