"""A write killed by SIGKILL leaves its temporary file; the next write into that folder
removes it (issue #52, item 16). Only this machine's temporaries of processes that no longer
run are removed: a running writer's, another machine's and other files stay."""

from __future__ import annotations

import os
import signal
import subprocess
import sys

from csgs_codec import atomic_write
from csgs_codec.atomic_write import remove_stale_temporaries, write_atomically

#: A writer that stops for good just before its rename, so that it can be killed mid-write.
KILLED_WRITER = """
import os, sys, time
from csgs_codec import atomic_write
os.fsync = lambda fd: (print("writing", flush=True), time.sleep(60))
atomic_write.write_atomically(sys.argv[1], b"never renamed")
"""


def _dead_pid() -> int:
    done = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    return int(done.stdout)


def test_a_temporary_left_by_sigkill_is_removed_by_the_next_write(tmp_path):
    out = tmp_path / "scene.csgs"
    writer = subprocess.Popen([sys.executable, "-c", KILLED_WRITER, str(out)],
                              stdout=subprocess.PIPE, text=True)
    assert writer.stdout.readline().strip() == "writing"
    writer.send_signal(signal.SIGKILL)
    writer.wait(timeout=30)
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].endswith(".tmp") and not out.exists()
    write_atomically(out, b"data")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.csgs"]
    assert out.read_bytes() == b"data"


def test_only_dead_local_writers_temporaries_are_removed(tmp_path):
    host = atomic_write._HOST
    dead = f".a.ply.{host}-{_dead_pid()}.k2j4_x9q.tmp"
    mine = f".b.ply.{host}-{os.getpid()}.abcdefgh.tmp"
    other_host = f".c.ply.{'elsewhere' if host != 'elsewhere' else 'other'}-1.abcdefgh.tmp"
    unrelated = ".d.ply.tmp"
    for name in (dead, mine, other_host, unrelated):
        (tmp_path / name).write_bytes(b"")
    assert remove_stale_temporaries(tmp_path) == [dead]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([mine, other_host, unrelated])
    (tmp_path / dead).write_bytes(b"")
    assert remove_stale_temporaries(tmp_path) == []  # a folder is looked at once per process


def test_temporary_names_say_whose_they_are(tmp_path, monkeypatch):
    seen = []
    real_replace = os.replace

    def replace(source, target):
        seen.append(os.path.basename(source))
        real_replace(source, target)

    monkeypatch.setattr(os, "replace", replace)
    write_atomically(tmp_path / "x.bin", b"1")
    assert atomic_write._TEMPORARY.fullmatch(seen[0])
    assert f".x.bin.{atomic_write._HOST}-{os.getpid()}." in seen[0]
