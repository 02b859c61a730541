"""Outputs never destroy inputs (issue #20, item 3).

Rules: an output that is the input (same inode: same name, a hard link or a symlink to it) is
refused with exit 2 and the input left as it was; a symlink output is written through to its
target and stays a link; a non-regular target (FIFO, folder) is refused and left alone; SIGTERM
during the final write removes the temporary file like Ctrl-C; an unwritable output location
is refused before the encode runs.
"""

from __future__ import annotations

import os
import signal
import stat

import pytest

from csgs_cli.main import main
from csgs_codec.atomic_write import write_atomically
from csgs_codec.errors import InputError
from csgs_codec.format.layout import MAGIC
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene


@pytest.fixture
def ply(tmp_path):
    path = tmp_path / "scene.ply"
    write_ply(random_scene(64, sh_degree=0), path)
    return path


def _encode(src, out):
    return main(["encode", str(src), "-o", str(out), "-q", "--no-hyperprior"])


@pytest.mark.parametrize("how", ["same", "hardlink", "symlink"])
def test_encode_refuses_an_output_that_is_the_input(tmp_path, ply, capsys, how):
    before = ply.read_bytes()
    out = ply
    if how == "hardlink":
        out = tmp_path / "other.csgs"
        os.link(ply, out)
    elif how == "symlink":
        out = tmp_path / "other.csgs"
        out.symlink_to(ply)
    assert _encode(ply, out) == 2
    err = capsys.readouterr().err
    assert "is the input file" in err and "Traceback" not in err
    assert ply.read_bytes() == before


def test_decode_refuses_an_output_that_is_the_input(tmp_path, ply, capsys):
    csgs = tmp_path / "x.csgs"
    assert _encode(ply, csgs) == 0
    before = csgs.read_bytes()
    assert main(["decode", str(csgs), "-o", str(csgs), "-q"]) == 2
    assert "is the input file" in capsys.readouterr().err
    assert csgs.read_bytes() == before


def test_a_symlink_output_is_written_through_and_stays_a_link(tmp_path, ply):
    target = tmp_path / "real.csgs"
    target.write_bytes(b"old")
    link = tmp_path / "link.csgs"
    link.symlink_to(target)
    assert _encode(ply, link) == 0
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_bytes().startswith(MAGIC)


def test_symlink_write_replaces_the_target_bytes(tmp_path):
    target = tmp_path / "real.bin"
    target.write_bytes(b"old")
    link = tmp_path / "link.bin"
    link.symlink_to(target)
    write_atomically(link, b"new bytes")
    assert link.is_symlink()
    assert target.read_bytes() == b"new bytes"


def test_non_regular_targets_are_refused(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file") as err:
        write_atomically(fifo, b"data")
    assert err.value.file == str(fifo)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    folder = tmp_path / "folder.ply"
    folder.mkdir()
    with pytest.raises(InputError, match="not a regular file"):
        write_atomically(folder, b"data")
    assert folder.is_dir()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["folder.ply", "pipe"]


def test_cli_refuses_a_non_regular_output(tmp_path, ply, capsys):
    fifo = tmp_path / "out.csgs"
    os.mkfifo(fifo)
    assert _encode(ply, fifo) == 2
    assert "not a regular file" in capsys.readouterr().err
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)


def test_sigterm_during_the_write_leaves_no_temporary_file(tmp_path, monkeypatch):
    out = tmp_path / "out.bin"
    out.write_bytes(b"previous")
    real_fsync = os.fsync

    def fsync_then_terminated(fd):
        real_fsync(fd)
        os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(os, "fsync", fsync_then_terminated)
    handler = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt):
        write_atomically(out, b"new data")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
    assert out.read_bytes() == b"previous"
    assert signal.getsignal(signal.SIGTERM) == handler


def test_an_unwritable_output_is_refused_before_the_encode(tmp_path, ply, capsys, monkeypatch):
    from csgs_codec.codec.encoder import Encoder

    def never(self, scene):
        raise AssertionError("the encode ran before the output was checked")

    monkeypatch.setattr(Encoder, "encode_with_report", never)
    out = tmp_path / "missing" / "out.csgs"
    assert _encode(ply, out) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and "out.csgs" in err


def test_no_command_prints_help_to_stderr_with_exit_2(capsys):
    assert main([]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "usage: csgs" in captured.err


def test_a_device_node_target_is_refused_and_stays_a_device(tmp_path, ply, capsys):
    # A private copy of /dev/null's node, so a broken rule could never replace a real device.
    node = tmp_path / "null"
    try:
        os.mknod(node, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except (PermissionError, OSError) as exc:
        pytest.skip(f"cannot create a device node here: {exc}")
    assert _encode(ply, node) == 2
    assert "not a regular file" in capsys.readouterr().err
    assert stat.S_ISCHR(os.stat(node).st_mode)
