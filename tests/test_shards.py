"""A sweep split into shards (one database each, with or without per-step rows) and joined by
``pathpref db merge``: the joined database holds each episode once, exactly as one whole run
stores it; batched claims and writes keep a chunk's episodes together."""

from __future__ import annotations

import shutil
import sqlite3

import pytest

from pathpref.apps.cli import main
from pathpref.errors import ConfigError
from pathpref.experiments.backends import chunk_size, failed
from pathpref.experiments.migrate import merge_databases
from pathpref.experiments.store import ResultStore
from pathpref.experiments.sweep import parse_shard, run_sweep, shard_specs, sweep_specs

ROWS = "key, status, success, goal_reached, violations, steps, inputs, start, goals"


def specs():
    return sweep_specs("simple", ["compliant", "goal_only"], [1, 5], instances=2, runs=2,
                       queries=100)


def rows(db, what=ROWS, name="episodes"):
    with sqlite3.connect(db) as c:
        return c.execute(f"SELECT {what} FROM {name} ORDER BY {what}").fetchall()


def test_shards_are_disjoint_cover_the_sweep_and_depend_on_the_key_alone():
    s = specs()
    parts = [shard_specs(s, i, 3) for i in range(3)]
    keys = [x.key() for p in parts for x in p]
    assert sorted(keys) == sorted(x.key() for x in s)  # each episode in exactly one shard
    assert all(parts)  # 16 episodes over 3 shards: none empty (the hash spreads them)
    # an episode's shard does not depend on the rest of the sweep or its order
    assert [x.key() for x in shard_specs(s[::-1][:7], 1, 3)] == \
        [x.key() for x in s[::-1][:7] if x.key() in {y.key() for y in parts[1]}]
    assert parse_shard("2/3") == (2, 3)
    for bad in ("3/3", "1", "-1/2", "a/b", "1/0"):
        with pytest.raises(ConfigError, match="I/N"):
            parse_shard(bad)


def test_chunks_shrink_near_the_end_of_a_sweep():
    assert chunk_size(1000, 2, 8) == 8
    assert chunk_size(12, 2, 8) == 3
    assert chunk_size(3, 2, 8) == 1 and chunk_size(0, 2, 8) == 1


def test_merged_shards_equal_one_whole_run(tmp_path, capsys):
    s = specs()
    whole, a, b, out = (str(tmp_path / f"{n}.sqlite") for n in ("whole", "a", "b", "out"))
    run_sweep(s, whole, workers=2, progress=False)
    run_sweep(shard_specs(s, 0, 2), a, workers=1, progress=False)
    run_sweep(shard_specs(s, 1, 2), b, workers=2, progress=False, steps=False)
    assert rows(b, "key", "steps") == []  # --no-steps: episode rows only
    r = merge_databases(out, [a, b])
    assert r["copied"] == len(s) == r["episodes"] and r["duplicates"] == r["conflicts"] == 0
    assert rows(out) == rows(whole)
    kept = {k for (k,) in rows(a, "key")}
    assert rows(out, "key, t, x, y, action", "steps") == [
        x for x in rows(whole, "key, t, x, y, action", "steps") if x[0] in kept]
    # again: every key is there already, nothing changes
    assert main(["db", "merge", out, a, b]) == 0
    assert f"0 episodes copied (0 step rows), 0 failed ones replaced by finished ones, " \
           f"{len(s)} already there left out (0 with another outcome)" in capsys.readouterr().out
    assert rows(out) == rows(whole)


def test_merge_replaces_failed_rows_counts_conflicts_and_refuses_bad_inputs(tmp_path, capsys):
    s = specs()[:4]
    a, b, out = (str(tmp_path / f"{n}.sqlite") for n in ("a", "b", "out"))
    run_sweep(s, a, workers=1, progress=False)
    with ResultStore(out) as st:  # the output holds a failed attempt of the first episode
        st.add(failed(s[0], "worker process died 3 times"))
    shutil.copy(a, b)
    with sqlite3.connect(b) as c:  # another outcome of an ok episode (not pathpref's doing)
        c.execute("UPDATE episodes SET inputs = inputs + 1 WHERE key = ?", (s[1].key(),))
    r = merge_databases(out, [a])
    assert (r["copied"], r["replaced"], r["duplicates"]) == (3, 1, 0)
    assert rows(out) == rows(a)
    assert main(["db", "merge", out, b]) == 2  # the disagreeing run is refused, named
    err = capsys.readouterr().err
    assert f"{out} and {b} disagree on episode goal_only ΔT=1 instance 0 run 0" in err
    assert "inputs = " in err and len(err.splitlines()) == 1
    assert rows(out) == rows(a)  # the output's rows kept
    with pytest.raises(ConfigError, match="is the output database"):
        merge_databases(out, [out])
    with pytest.raises(ConfigError, match="given twice"):
        merge_databases(str(tmp_path / "new.sqlite"), [a, a])


def test_a_chunk_is_claimed_in_one_go_and_claims_of_others_are_left(tmp_path):
    s = specs()[:3]
    db = str(tmp_path / "c.sqlite")
    other = {"host": "elsewhere", "pid": 1, "start": "0"}
    with ResultStore(db) as st:
        st.add(failed(s[2], "boom"))
        assert st.claim(failed(s[0], ""), owner=other) == "claimed"
        got = st.claim_many([failed(x, "") for x in s], max_age_s=1e9)
        assert got == ["busy", "claimed", "done"]
        assert st.claim_many([failed(s[2], "")], retry_failed=True) == ["claimed"]
        assert st.release_claims() == 2


def test_a_dead_workers_chunk_is_rerun_without_claiming_it_again(tmp_path, monkeypatch):
    """A worker killed in the middle of its chunk: the episode it ran is charged once and run
    again, the rest of its chunk is run uncharged by whichever worker is free, and no episode
    is claimed twice or lost."""
    import os
    import signal

    from pathpref.experiments import backends

    s = specs()  # 16 episodes over 2 workers: chunks of 4
    target, marker = s[1].key(), tmp_path / "killed"
    real = backends.run_episode

    def run(spec):
        if spec.key() == target and not marker.exists():
            marker.write_text("x")
            os.kill(os.getpid(), signal.SIGKILL)
        return real(spec)

    monkeypatch.setattr(backends, "run_episode", run)
    asked: list[str] = []

    def claim(chunk):
        asked.extend(x.key() for x in chunk)
        return chunk

    out = [r for batch in backends.local_batches(s, 2, claim=claim) for r in batch]
    assert marker.exists()
    assert sorted(r.spec.key() for r in out) == sorted(asked) == sorted(x.key() for x in s)
    assert {r.status for r in out} == {"ok"}
    marker.unlink()  # the same through a sweep, which claims in its database
    db = str(tmp_path / "d.sqlite")
    counts = run_sweep(s, db, workers=2, progress=False)
    assert marker.exists() and counts["ran"] == len(s) and counts["failed"] == 0
    assert rows(db, "key, status") == sorted((x.key(), "ok") for x in s)
