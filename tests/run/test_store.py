"""The results store: rows round-trip, a writer killed mid-insert leaves no half row, and two
processes writing at once both land."""

import multiprocessing as mp
import os

import pytest

from lensmount.run.store import Store, default_path
from tests.loop.runs import paths, write_run


def test_record_round_trips(tmp_path):
    s = write_run(tmp_path / "r", 1.5e-3, 2e-5)
    s["stray_fraction_bias_bound"] = 4e-6
    with Store(tmp_path / "runs.sqlite") as store:
        rid = store.record(s, paths(tmp_path / "r"))
        (row,) = store.runs(design_path=tmp_path / "r")
    assert row.id == rid and row.stray_fraction == 1.5e-3 and row.stray_fraction_std_error == 2e-5
    assert row.stray_fraction_bias_bound == 4e-6
    assert row.per_part["barrel"]["fraction"] == 1.5e-3
    assert row.summary_path == str(tmp_path.resolve() / "rows" / str(rid) / "summary.json")
    assert row.lens_sha256 == "l" * 64 and row.git_commit is None and row.git_dirty is None


def test_a_row_keeps_its_own_artefacts_when_the_run_folder_is_rewritten(tmp_path):
    """`simulate --resume` into the same --out rewrites that folder; the earlier row's files must
    still hold the earlier run (they are the row's own copy)."""
    import json

    from lensmount.run.results import read_exr

    run = tmp_path / "out"
    with Store(tmp_path / "store" / "runs.sqlite") as store:
        first = store.record(write_run(run, 1.0e-3, 1e-5, passes=4), paths(run))
        second = store.record(write_run(run, 1.2e-3, 1e-5, passes=8), paths(run))  # the resumed run, same folder
        rows = {r.id: r for r in store.runs()}
    for rid, value, passes in ((first, 1.0e-3, 4), (second, 1.2e-3, 8)):
        row = rows[rid]
        assert row.out_dir == str(tmp_path.resolve() / "store" / "rows" / str(rid))
        summary = json.loads(open(row.summary_path).read())
        assert (summary["stray_fraction"], summary["passes"]) == (value, passes)
        assert read_exr(row.image_path)["Y"].max() == value and os.path.isfile(row.preview_path)
    assert sorted(os.listdir(tmp_path / "store" / "rows")) == [str(first), str(second)]  # no partial folder left


def test_store_location(tmp_path, monkeypatch):
    monkeypatch.delenv("LENSMOUNT_STORE", raising=False)
    assert default_path(tmp_path) == tmp_path.resolve() / ".lensmount" / "runs.sqlite"
    monkeypatch.setenv("LENSMOUNT_STORE", str(tmp_path / "shared.sqlite"))
    assert default_path(tmp_path) == tmp_path / "shared.sqlite"
    assert default_path(tmp_path, tmp_path / "x.sqlite") == tmp_path / "x.sqlite"


def _die_during_insert(db_path, folder):
    from lensmount.run.store import Store
    from tests.loop.runs import paths, write_run

    store = Store(db_path)
    summary = write_run(folder, 1.0, 0.1)
    store.db.set_progress_handler(lambda: os._exit(3), 1)  # the process dies inside the INSERT
    store.record(summary, paths(folder))


def test_a_writer_killed_mid_insert_leaves_no_row(tmp_path):
    db = tmp_path / "runs.sqlite"
    Store(db).close()
    p = mp.get_context("spawn").Process(target=_die_during_insert, args=(db, tmp_path / "r"))
    p.start()
    p.join(60)
    assert p.exitcode == 3
    with Store(db) as store:
        assert store.runs() == []
        store.record(write_run(tmp_path / "r2", 2.0, 0.1), paths(tmp_path / "r2"))
        assert len(store.runs()) == 1


def _writer(db_path, folder, n, barrier):
    from lensmount.run.store import Store
    from tests.loop.runs import paths, write_run

    summary = write_run(folder, 1.0, 0.1)
    with Store(db_path) as store:
        barrier.wait()
        for _ in range(n):
            store.record(summary, paths(folder))


@pytest.mark.timeout(120)
def test_two_processes_writing_at_once_both_land(tmp_path):
    ctx = mp.get_context("spawn")
    barrier = ctx.Barrier(2)
    db = tmp_path / "runs.sqlite"
    procs = [ctx.Process(target=_writer, args=(db, tmp_path / f"r{i}", 25, barrier)) for i in range(2)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(100)
    assert [p.exitcode for p in procs] == [0, 0]
    with Store(db) as store:
        runs = store.runs()
    assert len(runs) == 50 and len({r.id for r in runs}) == 50
    assert sorted({r.design_path for r in runs}) == sorted(str((tmp_path / f"r{i}").resolve()) for i in range(2))
    assert all(r.out_dir == str(tmp_path.resolve() / "rows" / str(r.id)) and os.path.isfile(r.summary_path)
               for r in runs)  # every row got its own copy


def test_a_store_made_before_the_test_condition_column_opens_and_records(tmp_path):
    import sqlite3

    path = tmp_path / "runs.sqlite"
    with Store(path) as store:
        store.record(write_run(tmp_path / "r", 1.0, 0.1), paths(tmp_path / "r"))
        store.db.execute("ALTER TABLE runs DROP COLUMN condition_sha256")  # the first schema
    assert "condition_sha256" not in {r[1] for r in sqlite3.connect(path).execute("PRAGMA table_info(runs)")}
    summary = write_run(tmp_path / "s", 2.0, 0.1)
    summary["provenance"]["condition_sha256"] = "c" * 64
    with Store(path) as store:
        store.record(summary, paths(tmp_path / "s"))
        old, new = store.runs()
        assert (old.condition_sha256, new.condition_sha256) == (None, "c" * 64)
        assert [r.id for r in store.runs(condition_sha256="c" * 64)] == [old.id, new.id]  # an old row may match
        assert store.runs(condition_sha256="d" * 64) == [old]


def test_the_store_keeps_input_files_by_content_and_puts_them_back_together(tmp_path):
    import hashlib

    from lensmount.run.store import Store

    mount, scene = b"[hood]\nlength_mm = 100.0\n", b"[source]\n"
    sha = {name: hashlib.sha256(data).hexdigest() for name, data in (("mount", mount), ("scene", scene))}
    with Store(tmp_path / "runs.sqlite") as store:
        store.keep_inputs({sha["mount"]: mount, sha["scene"]: scene})
        store.keep_inputs({sha["mount"]: mount})  # kept once: the same content is the same file
        inputs = {"mount.toml": sha["mount"], "scenes/case2.toml": sha["scene"]}
        copy = store.restore_inputs(inputs, "k", ("marker.json", "{}"))
        assert (copy / "mount.toml").read_bytes() == mount and (copy / "scenes" / "case2.toml").read_bytes() == scene
        assert (copy / "marker.json").read_text() == "{}"
        assert store.restore_inputs(inputs, "k", ("marker.json", "{}")) == copy
        assert store.restore_inputs({"lens.toml": "0" * 64}, "missing", ("m", "")) is None  # not kept: no copy
        assert store.restore_inputs({"../../outside": sha["mount"]}, "out", ("m", "")) is None
    assert len(list((tmp_path / "inputs").glob("*"))) == 3  # two files and designs/
    assert not (tmp_path / "outside").exists()
