"""A replaced output keeps its mode and owner (issue #29, item 2).

Rules: writing over an existing file keeps that file's permission bits, and its owner and
group where this process may set them; a new file gets the ordinary mode (0666 less the
umask). Every command that writes through the atomic writer follows them.
"""

from __future__ import annotations

import os
import stat

import pytest

from csgs_cli.main import main
from csgs_codec.atomic_write import write_atomically
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@pytest.fixture
def ply(tmp_path):
    path = tmp_path / "scene.ply"
    write_ply(random_scene(64, sh_degree=0), path)
    return path


def test_a_replaced_file_keeps_its_mode(tmp_path):
    out = tmp_path / "out.bin"
    out.write_bytes(b"old")
    os.chmod(out, 0o640)
    write_atomically(out, b"new")
    assert out.read_bytes() == b"new"
    assert _mode(out) == 0o640


def test_a_new_file_gets_the_umask_default(tmp_path):
    out = tmp_path / "new.bin"
    write_atomically(out, b"new")
    assert _mode(out) == 0o666 & ~_umask()


def test_a_symlinked_output_keeps_its_targets_mode(tmp_path):
    target = tmp_path / "real.bin"
    target.write_bytes(b"old")
    os.chmod(target, 0o600)
    link = tmp_path / "link.bin"
    link.symlink_to(target)
    write_atomically(link, b"new")
    assert link.is_symlink() and _mode(target) == 0o600


def test_a_replaced_file_keeps_its_owner_where_permitted(tmp_path):
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        pytest.skip("only root may give a file to another owner")
    out = tmp_path / "owned.bin"
    out.write_bytes(b"old")
    os.chown(out, 12345, 23456)
    write_atomically(out, b"new")
    info = os.stat(out)
    assert (info.st_uid, info.st_gid) == (12345, 23456)


def test_encode_over_a_private_file_keeps_it_private(tmp_path, ply, capsys):
    out = tmp_path / "p.csgs"
    out.write_bytes(b"old")
    os.chmod(out, 0o600)
    assert main(["encode", str(ply), "-o", str(out), "-q", "--no-hyperprior"]) == 0
    assert _mode(out) == 0o600
    assert "Traceback" not in capsys.readouterr().err


def test_decode_over_a_private_file_keeps_it_private(tmp_path, ply, capsys):
    csgs = tmp_path / "x.csgs"
    assert main(["encode", str(ply), "-o", str(csgs), "-q", "--no-hyperprior"]) == 0
    out = tmp_path / "back.ply"
    out.write_bytes(b"old")
    os.chmod(out, 0o604)
    assert main(["decode", str(csgs), "-o", str(out), "-q"]) == 0
    assert _mode(out) == 0o604
    assert "Traceback" not in capsys.readouterr().err
