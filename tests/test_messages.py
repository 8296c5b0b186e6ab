"""User-facing errors from files and flags are one line, read alike (deepphy.messages)."""

from __future__ import annotations

import pytest

from deepphy.models.config import ModelsFileError, load_models
from deepphy.suite import SuiteError, load_suite


def test_a_models_file_that_is_not_yaml_is_one_line(tmp_path):
    bad = tmp_path / "models.yaml"
    bad.write_text("models:\n  - name: a\n    provider: [openai\n")  # PyYAML's message spans lines
    with pytest.raises(ModelsFileError) as caught:
        load_models(bad)
    message = str(caught.value)
    assert "\n" not in message and message.startswith(f"models file {bad}: not valid YAML (")


def test_a_models_file_and_a_suite_file_name_the_field_that_is_wrong(tmp_path):
    models = tmp_path / "models.yaml"
    models.write_text("models:\n  - name: a\n    provider: openai\n    rpm: many\n")
    with pytest.raises(ModelsFileError, match=r"models file .*: models\.0\.\S+: ") as caught:
        load_models(models)
    assert "Value error" not in str(caught.value)
    suite = tmp_path / "s.yaml"
    suite.write_text("name: s\nenvs:\n  - env: iphyre\n    limit: 0\n")
    with pytest.raises(SuiteError, match=r"suite file .*: envs\.0\.limit: .*greater than or equal to 1"):
        load_suite(str(suite))
