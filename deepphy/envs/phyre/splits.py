"""PHYRE's evaluation setups and folds, reproduced from `phyre.metrics` (phyre 0.2.2).

Every shuffle is PHYRE's `stable_shuffle`: sort by md5(str(item) + salt). For fold `seed`:
- `ball_within_template`: each template's tasks shuffled with salt
  `ball_online_ind_tasks{seed}`; the first round(0.8 n) are train, the rest test (20 per
  template, 500 in all). Dev: the 2000 train tasks shuffled with salt `make_dev{seed}`, the
  first int(0.8 n) = 1600 stay train, the other 400 are dev.
- `ball_cross_template`: the 25 templates shuffled with salt
  `ball_cross_template_half_{seed}`; the first round(0.8 n) = 20 are train, the last 5
  test (500 tasks). Dev: those 20 shuffled with salt `dev_ball_cross_template_half_{seed}`;
  the first int(0.8 n) = 16 stay train, the other 4 are dev.
Split lists are sorted by task id, as `phyre.get_fold` returns them.
"""

from __future__ import annotations

import hashlib
from typing import Iterable, Literal

SETUPS = {"within": "ball_within_template", "cross": "ball_cross_template"}
FOLDS = 10
TRAIN_SHARE = 0.8

Setup = Literal["within", "cross"]
Split = Literal["train", "dev", "test"]


def stable_shuffle(items: Iterable[str], salt: str = "") -> list[str]:
    """PHYRE's `phyre.util.stable_shuffle`."""
    return sorted(items, key=lambda s: hashlib.md5((str(s) + salt).encode("utf8")).hexdigest())


def by_template(task_ids: Iterable[str]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for task_id in task_ids:
        out.setdefault(task_id.split(":")[0], []).append(task_id)
    return out


def get_fold(setup: Setup, fold: int, task_ids: Iterable[str]) -> dict[str, list[str]]:
    """{"train": [...], "dev": [...], "test": [...]} of PHYRE-B task ids (`task_ids`: all of them)."""
    if not 0 <= fold < FOLDS:
        raise ValueError(f"PHYRE fold must be 0..{FOLDS - 1}, got {fold}")
    per_template = by_template(task_ids)
    if setup == "within":
        train_pool, test = [], []
        for _, ids in sorted(per_template.items()):
            ids = stable_shuffle(ids, f"ball_online_ind_tasks{fold}")
            n_train = int(round(len(ids) * TRAIN_SHARE))
            train_pool += ids[:n_train]
            test += ids[n_train:]
        pool = stable_shuffle(train_pool, f"make_dev{fold}")
        n_train = int(len(pool) * TRAIN_SHARE)
        train, dev = pool[:n_train], pool[n_train:]
    elif setup == "cross":
        order = stable_shuffle(list(per_template), f"ball_cross_template_half_{fold}")
        n_train = int(round(len(order) * TRAIN_SHARE))
        test = [t for tpl in order[n_train:] for t in per_template[tpl]]
        dev_order = stable_shuffle(order[:n_train], f"dev_ball_cross_template_half_{fold}")
        n_dev_train = int(len(dev_order) * TRAIN_SHARE)
        train = [t for tpl in dev_order[:n_dev_train] for t in per_template[tpl]]
        dev = [t for tpl in dev_order[n_dev_train:] for t in per_template[tpl]]
    else:
        raise ValueError(f"unknown PHYRE setup {setup!r} (within, cross)")
    return {"train": sorted(train), "dev": sorted(dev), "test": sorted(test)}
