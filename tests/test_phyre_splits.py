"""PHYRE's evaluation setups and folds (phyre.metrics.get_fold), reproduced."""

from __future__ import annotations

import hashlib
import json
from collections import Counter

import pytest

from conftest import data_file

from deepphy.envs.phyre import data
from deepphy.envs.phyre.splits import get_fold, stable_shuffle

GROUND_TRUTH = data_file("phyre_real_grid_outcomes.json")  # real phyre 0.2.2


def templates(ids):
    return sorted({i.split(":")[0] for i in ids})


def test_stable_shuffle_sorts_by_md5_of_item_and_salt():
    items = ["00001:000", "00001:001", "00002:000", "00003:005"]
    out = stable_shuffle(items, "salt")
    keys = [hashlib.md5((i + "salt").encode()).hexdigest() for i in out]
    assert keys == sorted(keys) and sorted(out) == sorted(items)
    assert stable_shuffle(items, "other") != out


def test_fold0_cross_template_test_templates_are_phyres():
    fold = get_fold("cross", 0, data.task_ids())
    assert templates(fold["test"]) == ["00003", "00004", "00014", "00015", "00019"]


@pytest.mark.parametrize("fold", [0, 1, 7])
def test_split_sizes_and_disjointness(fold):
    ids = data.task_ids()
    within = get_fold("within", fold, ids)
    assert [len(within[s]) for s in ("train", "dev", "test")] == [1600, 400, 500]
    assert set(Counter(i.split(":")[0] for i in within["test"]).values()) == {20}
    cross = get_fold("cross", fold, ids)
    assert [len(templates(cross[s])) for s in ("train", "dev", "test")] == [16, 4, 5]
    assert [len(cross[s]) for s in ("train", "dev", "test")] == [1600, 400, 500]
    for split in (within, cross):
        parts = [set(split[s]) for s in ("train", "dev", "test")]
        assert set.union(*parts) == set(ids) and sum(map(len, parts)) == len(ids)
        assert all(split[s] == sorted(split[s]) for s in split)
    # the held-out templates' within-template test tasks are cross-template test tasks too
    assert len(set(within["test"]) & set(cross["test"])) == 100


def test_folds_differ():
    ids = data.task_ids()
    tests = [tuple(get_fold("cross", f, ids)["test"]) for f in range(10)]
    assert len(set(tests)) == 10
    assert get_fold("within", 0, ids)["test"] != get_fold("within", 1, ids)["test"]


def test_ground_truth_tasks_are_within_template_fold0_test_tasks():
    # The shared outcomes were recorded by real phyre on fold-0 within-template test tasks.
    recorded = set(json.loads(GROUND_TRUTH.read_text())["outcomes"])
    assert len(recorded) == 400
    assert recorded <= set(get_fold("within", 0, data.task_ids())["test"])


def test_bad_fold_or_setup():
    with pytest.raises(ValueError, match="fold"):
        get_fold("within", 10, data.task_ids())
    with pytest.raises(ValueError, match="setup"):
        get_fold("sideways", 0, data.task_ids())  # type: ignore[arg-type]
