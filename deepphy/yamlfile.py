"""A user's YAML file (a suite, a models file) read and validated as its pydantic model, with
every problem one line: unreadable, not YAML, or not what the model allows."""

from __future__ import annotations

from pathlib import Path
from typing import TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from deepphy.messages import one_line, validation_message

M = TypeVar("M", bound=BaseModel)


def read_yaml_model(path: Path, model: type[M], error: type[Exception], what: str) -> M:
    """`path` as `model`; an empty file is an empty mapping. Raises `error("<what> <path>:
    <problem>")`."""
    try:
        data = yaml.safe_load(path.read_text())
        return model.model_validate({} if data is None else data)
    except OSError as e:
        raise error(f"{what} {path}: {e.strerror or e}") from None
    except yaml.YAMLError as e:
        raise error(f"{what} {path}: not valid YAML ({one_line(str(e))})") from None
    except ValidationError as e:
        raise error(f"{what} {path}: {validation_message(e)}") from None
