"""What passes between deepphy and a model: images, chat messages, prompt formats, usage.

A leaf module (pydantic, numpy and OpenCV only): environments, prompts, models and run
records all import it, and it imports none of them. numpy and OpenCV are imported where an
image is encoded or decoded: the processes that only read records and prompts (the metrics
actor, a model worker, `deepphy report`) start ~0.15 s sooner without them.
"""

from __future__ import annotations

import hashlib
from enum import Enum
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Union

from pydantic import BaseModel, ConfigDict, model_validator

if TYPE_CHECKING:
    import numpy as np

# PNG encoding: deflate level 3 with no row filter. Encoding was the largest part of an
# I-PHYRE attempt's CPU (level 6 with libpng's adaptive filters: 11 ms per 600x600 image,
# 15 ms per Pooltool table); this takes 2-3 ms for files 0-60% larger (Pooltool 30 KiB as
# before, I-PHYRE 11 KiB instead of 7; benchmarks/cpu_per_attempt.py). Our renderings are
# flat colours, which the filters only make harder to compress. The pixels are identical.
PNG_COMPRESSION = 3


def image_digest(png: bytes) -> str:
    """The content address of an image: sha256 of its PNG bytes, hex (images/<digest>.png)."""
    return hashlib.sha256(png).hexdigest()


class Image(BaseModel):
    """A named RGB image, PNG-encoded once where it is rendered. `caption` says what it
    shows (it goes into the prompt).

    Observations carry PNG bytes, not arrays: they cross Ray, go into prompts as base64
    and are written to the run directory as key frames, and PNG is what all three need.
    An image already on disk (a key frame of an earlier attempt) may name its `file`
    instead: its bytes are read where the request is encoded, so thousands of waiting
    prompts do not hold their histories' images in the driver. Read bytes with `load()`.
    """

    model_config = ConfigDict(frozen=True)

    name: str
    caption: str
    png: bytes = b""
    file: str | None = None  # absolute path of the PNG, when the bytes are not carried

    @model_validator(mode="after")
    def _one_source(self) -> "Image":
        if (self.file is None) == (not self.png):
            raise ValueError(f"image {self.name!r} needs exactly one of png bytes and a file")
        return self

    def load(self) -> bytes:
        """The PNG bytes (read from `file` when the image names one)."""
        return self.png if self.file is None else Path(self.file).read_bytes()

    @cached_property
    def digest(self) -> str:
        """The content address of the image: sha256 of its PNG bytes, hex (images/<digest>.png
        of a run directory). Computed once per image: a prompt's digest, its stored JSON and
        the store's image file each need it. (Not a field: kept out of dumps and equality.)"""
        return image_digest(self.load())

    @classmethod
    def stored(cls, name: str, caption: str, file: str, digest: str | None = None) -> "Image":
        """An image by `file`, whose `digest` the caller may already know (a run store
        remembers the images it has written): then its bytes are not read to address it."""
        image = cls(name=name, caption=caption, file=file)
        if digest is not None:
            image.__dict__["digest"] = digest  # where cached_property keeps its value
        return image

    def loaded(self) -> "Image":
        """This image carrying its bytes (for a reader that does not share this file system)."""
        return self if self.file is None else Image(name=self.name, caption=self.caption, png=self.load())

    @classmethod
    def from_array(cls, name: str, caption: str, rgb: np.ndarray) -> "Image":
        # OpenCV and NumPy: only where pictures are made or read (every command imports chat)
        import cv2
        import numpy as np

        bgr = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR)
        params = [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION, cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
        ok, buf = cv2.imencode(".png", bgr, params)
        if not ok:
            raise ValueError(f"could not encode image {name!r}")
        return cls(name=name, caption=caption, png=buf.tobytes())

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) in pixels, read from the PNG header."""
        png = self.load()
        return int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")

    def to_array(self) -> np.ndarray:
        """Decode to an RGB uint8 array."""
        # OpenCV and NumPy: only where pictures are made or read (every command imports chat)
        import cv2
        import numpy as np

        bgr = cv2.imdecode(np.frombuffer(self.load(), np.uint8), cv2.IMREAD_COLOR)
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)


class PromptFormat(str, Enum):
    VLA = "vla"  # rules + observation (+ history) -> the action only
    WM = "wm"  # the same, but a prediction of the consequences comes before the action


class TextPart(BaseModel):
    type: Literal["text"] = "text"
    text: str


class ImagePart(BaseModel):
    type: Literal["image"] = "image"
    image: Image


class Message(BaseModel):
    role: Literal["system", "user", "assistant"]
    content: list[Union[TextPart, ImagePart]]

    @property
    def text(self) -> str:
        return "\n".join(p.text for p in self.content if isinstance(p, TextPart))

    @property
    def images(self) -> list[Image]:
        return [p.image for p in self.content if isinstance(p, ImagePart)]


class Usage(BaseModel):
    """Tokens and cost of model requests."""

    input_tokens: int = 0
    output_tokens: int = 0
    cost_usd: float = 0.0

    def __add__(self, other: "Usage") -> "Usage":
        return Usage(
            input_tokens=self.input_tokens + other.input_tokens,
            output_tokens=self.output_tokens + other.output_tokens,
            cost_usd=self.cost_usd + other.cost_usd,
        )
