# SPDX-License-Identifier: Apache-2.0
"""h4pin's zarr stores (atlas, sweep): told by their own attribute, not by a word in their
attributes; a user's store kept unless --overwrite; one writer at a time; a folder where a sweep
URDF goes refused in one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli_in_process

from h4pin import files
from h4pin.errors import ParameterError

pytest.importorskip("zarr")
pytest.importorskip("xarray")

from h4pin.mechanism import store  # noqa: E402
from h4pin.studies import atlas, sweep  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
SPEC = sweep.Spec(n_designs=4, seed=1, chunk=2, task=sweep.Task(half=(0.1, 0.1, 0.05, 0.2), counts=(2, 2, 2, 2)),
                  volume=sweep.VolumeGrid(counts=(3, 3, 3)))


def user_store(path: Path, attrs: dict) -> Path:
    """A zarr 3 group at ``path`` with ``attrs`` and one file of the user's data."""
    path.mkdir()
    (path / "zarr.json").write_text(json.dumps({"zarr_format": 3, "node_type": "group", "attributes": attrs}))
    (path / "data.bin").write_bytes(b"the user's own data")
    return path


def errors(err: str) -> str:
    """stderr without the note of a first run that compiles the kernels (cli.note_first_compile)."""
    return "".join(line for line in err.splitlines(keepends=True) if not line.startswith("h4pin: first run"))


def snapshot(path: Path) -> dict[str, bytes]:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def small_atlas(proto):
    return atlas.atlas(proto, [-0.05, 0.05], [0.0], [-0.6], progress=False)


def test_the_tag_alone_makes_a_store_h4pins(tmp_path, small_atlas):
    """The attribute with a known format and version, nothing else: an atlas and a sweep store
    carry it; a user's store that says kind: atlas (or holds the word h4pin), one of an older
    h4pin (h4pin: atlas, no tag), one of a future format version and one with a malformed tag do not."""
    a = store.save(small_atlas, tmp_path / "a.zarr")
    s = sweep.run(tmp_path / "s.zarr", SPEC, stop_after=0, progress=False)
    assert s["done"].tolist() == [False, False]
    assert files.store_format(a) == "atlas" and files.store_format(tmp_path / "s.zarr") == "sweep"
    assert files.written_by_h4pin(a) and files.written_by_h4pin(tmp_path / "s.zarr")
    assert "h4pin_store" not in store.open_store(a).attrs  # the store's tag, not the atlas's data
    others = {"kind": {"kind": "atlas", "note": "h4pin", "h4pin_stores": "atlas"},
              "older": {"h4pin": "atlas", "title": "H4 workspace atlas"},
              "future": {"h4pin_store": {"format": "atlas", "version": 2}},
              "text_version": {"h4pin_store": {"format": "atlas", "version": "1"}},
              "bool_version": {"h4pin_store": {"format": "atlas", "version": True}},
              "list": {"h4pin_store": ["atlas", 1]}}
    for name, attrs in others.items():
        path = user_store(tmp_path / f"{name}.zarr", attrs)
        assert files.store_format(path) is None and not files.written_by_h4pin(path), name


@pytest.mark.parametrize(("attrs", "reason"), [
    ({"kind": "atlas"}, "exists and h4pin did not write it"),
    ({"h4pin": "atlas", "title": "H4 workspace atlas"}, "was written by an older h4pin (its attributes hold no "
                                                        "h4pin_store)"),
    ({"h4pin_store": {"format": "atlas", "version": 2}}, "is an h4pin atlas store of format version 2, which this "
                                                         "h4pin (version 1) does not read"),
    ({"h4pin_store": {"format": "sweep", "version": 1}}, "is an h4pin sweep store, not an atlas")])
def test_a_users_store_is_kept_and_refused_in_one_line(tmp_path, monkeypatch, capsys, attrs, reason):
    """``h4pin atlas --out`` over a zarr store h4pin did not write: exit 2, one line naming why,
    the store byte for byte as it was."""
    path = user_store(tmp_path / "mine.zarr", attrs)
    before = snapshot(path)
    code, _, err = run_cli_in_process(["atlas", "--x", "-0.1", "0.1", "2", "--y", "0", "0.1", "2", "--quiet",
                                       "--out", str(path)], monkeypatch, capsys)
    assert code == 2
    assert errors(err) == f"error: --out {path} {reason}: give another path, or --overwrite to replace it\n"
    assert snapshot(path) == before and sorted(p.name for p in tmp_path.iterdir()) == ["mine.zarr"]


def test_overwrite_replaces_a_zarr_store_never_another_folder(tmp_path, small_atlas):
    """--overwrite (overwrite=True) replaces a user's zarr store by an atlas, and a user's zarr
    store by a new sweep; a folder that is not a zarr store is refused even then."""
    path = user_store(tmp_path / "mine.zarr", {"kind": "atlas"})
    with pytest.raises(ParameterError, match="h4pin did not write it"):
        store.save(small_atlas, path)
    store.save(small_atlas, path, overwrite=True)
    assert files.store_format(path) == "atlas" and not (path / "data.bin").exists()
    assert store.open_store(path).equals(small_atlas)

    other = user_store(tmp_path / "other.zarr", {"kind": "sweep", "spec": SPEC.to_json()})
    with pytest.raises(ParameterError, match="other.zarr exists and h4pin did not write it"):
        sweep.run(other, SPEC, stop_after=0, progress=False)
    assert (other / "data.bin").exists()
    res = sweep.run(other, SPEC, stop_after=1, progress=False, overwrite=True)
    assert res["done"].tolist() == [True, False] and files.store_format(other) == "sweep"
    assert not (other / "data.bin").exists()

    plain = tmp_path / "photos.zarr"
    plain.mkdir()
    (plain / "cat.jpg").write_bytes(b"\xff\xd8")
    for call in (lambda: store.save(small_atlas, plain, overwrite=True),
                 lambda: sweep.run(plain, SPEC, progress=False, overwrite=True)):
        with pytest.raises(ParameterError, match="is not a zarr store: give a new path"):
            call()
    assert [p.name for p in plain.iterdir()] == ["cat.jpg"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.zarr", "other.zarr", "photos.zarr"]


def test_a_sweep_resumes_only_its_own_store(tmp_path):
    """A store of an older h4pin (h4pin: sweep, no tag) is not resumed: refused, kept."""
    path = user_store(tmp_path / "old.zarr", {"h4pin": "sweep", "spec": SPEC.to_json()})
    with pytest.raises(ParameterError, match="written by an older h4pin") as info:
        sweep.run(path, SPEC, progress=False)
    assert "--overwrite" in str(info.value) and (path / "data.bin").exists()


def test_a_second_writer_of_one_store_is_refused_while_the_first_runs(tmp_path, monkeypatch):
    """Two threads creating one new sweep store: the second is refused in one typed line while
    the first holds the store; the first finishes; afterwards the store can be resumed."""
    path = tmp_path / "s.zarr"
    inside, go = threading.Event(), threading.Event()
    real = sweep.designs

    def slow_designs(spec):  # called once the first run holds the lock, while it creates the store
        inside.set()
        assert go.wait(60)
        return real(spec)

    monkeypatch.setattr(sweep, "designs", slow_designs)
    results = {}
    first = threading.Thread(target=lambda: results.update(first=sweep.run(path, SPEC, progress=False)))
    first.start()
    try:
        assert inside.wait(60)
        with pytest.raises(ParameterError) as info:
            sweep.run(path, SPEC, progress=False)
        assert str(info.value) == (f"another h4pin sweep (process {os.getpid()}) is writing {path} now: wait for it "
                                   "to finish, or give another path")
    finally:
        go.set()
        first.join(60)
    assert results["first"]["done"].all()
    assert sweep.run(path, SPEC, progress=False)["done"].all()  # the lock was released
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.zarr"]


def test_a_second_process_is_refused_in_one_line(tmp_path, small_atlas):
    """While this process writes a store (holds its lock), ``h4pin sweep`` and ``h4pin atlas``
    into it from another process exit 2 with one line naming this process; nothing is made."""
    target = tmp_path / "s.zarr"
    with files.store_lock(target, "sweep"):
        out = subprocess.run([sys.executable, "-m", "h4pin.cli", "sweep", "--out", str(target), "--designs", "4",
                              "--chunk", "2", "--quiet"], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert out.returncode == 2, out.stderr
    assert errors(out.stderr) == (f"error: another h4pin sweep (process {os.getpid()}) is writing {target} now: "
                                  "wait for it to finish, or give another path\n")
    assert not target.exists() and not list(tmp_path.iterdir())
    with files.store_lock(tmp_path / "a.zarr", "atlas"), pytest.raises(ParameterError, match="another h4pin atlas"):
        store.save(small_atlas, tmp_path / "a.zarr")
    assert not list(tmp_path.iterdir())


def test_a_lock_left_by_a_killed_process_is_taken_over(tmp_path):
    """A lock file whose holder died (no flock on it) is taken; a held one is not, by another
    caller in the same process either; released, the file is gone."""
    lock = tmp_path / ".s.zarr.h4pin-lock"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    lock.write_text(dead.stdout.strip())
    assert files.take_lock(lock) and files.lock_holder(lock) == os.getpid()
    assert not files.take_lock(lock)
    files.release_lock(lock)
    assert not lock.exists()
    files.release_lock(lock)  # not held: nothing


def test_a_folder_where_a_sweep_urdf_goes_is_one_line(tmp_path, monkeypatch, capsys):
    """A folder named like one of the URDFs the sweep writes: the command refuses it before any
    work (exit 2, one line, no store made); write_best refuses it before writing any file."""
    urdfs = tmp_path / "urdfs"
    urdfs.mkdir()
    (urdfs / "h4_sweep_3.urdf").mkdir()
    code, _, err = run_cli_in_process(["sweep", "--out", str(tmp_path / "s.zarr"), "--designs", "4", "--chunk", "2",
                                       "--quiet", "--urdf-dir", str(urdfs)], monkeypatch, capsys)
    assert code == 2, err
    assert errors(err) == (f"error: --urdf-dir {urdfs / 'h4_sweep_3.urdf'} is a folder: give the path of the file "
                           "to write\n")
    assert not (tmp_path / "s.zarr").exists()
    res = {"reach_all": np.array([True, True]), "worst": np.array([1.0, 2.0]), "volume": np.array([1.0, 3.0]),
           "designs": sweep.designs(sweep.Spec(n_designs=2, seed=0, chunk=2))}
    (urdfs / "h4_sweep_0.urdf").mkdir()
    with pytest.raises(ParameterError, match="h4_sweep_0.urdf is a folder"):
        sweep.write_best(res, urdfs, k=2)
    assert sorted(p.name for p in urdfs.iterdir()) == ["h4_sweep_0.urdf", "h4_sweep_3.urdf"]
