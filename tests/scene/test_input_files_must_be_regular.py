"""Every scene, camera and .csgs reader reads regular files only: a device, FIFO or folder
given as a file is an InputError naming the file, raised before anything is read (so
``/dev/zero`` cannot exhaust memory and a FIFO cannot block); a symlink to a regular file
reads as that file."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from csgs_codec.codec.decoder import Decoder
from csgs_codec.codec.files import read_scene
from csgs_codec.errors import InputError
from csgs_codec.interchange import detect_format, read_interchange
from csgs_codec.interchange.anchor_ply import read_anchor_ply
from csgs_codec.interchange.ply_io import read_ply
from csgs_codec.interchange.ply_mmap import MappedPly
from csgs_codec.interchange.sog import read_sog
from csgs_codec.scene.cameras_io import load_cameras
from csgs_codec.scene.colmap_io import load_colmap_cameras
from csgs_codec.untrusted import read_regular

REPO = Path(__file__).resolve().parents[2]
FORMATS = REPO / "tests" / "data" / "formats"
CAMERAS = REPO / "tests" / "data" / "cameras"

pytestmark = pytest.mark.skipif(not Path("/dev/zero").exists() or not hasattr(os, "mkfifo"),
                                reason="needs /dev/zero and FIFOs")


def _zero_link(tmp_path: Path, name: str) -> Path:
    link = tmp_path / name
    link.symlink_to("/dev/zero")
    return link


def _fifo(tmp_path: Path, name: str) -> Path:
    path = tmp_path / name
    os.mkfifo(path)
    return path


READERS = {
    "read_scene": read_scene,
    "read_interchange": read_interchange,
    "detect_format": detect_format,
    "read_ply": read_ply,
    "MappedPly": MappedPly,
    "read_anchor_ply": read_anchor_ply,
    "read_sog": read_sog,
    "load_cameras": load_cameras,
    "Decoder.decode": lambda path: Decoder().decode(path),
    "read_regular": read_regular,
}


@pytest.mark.parametrize("reader", sorted(READERS))
@pytest.mark.parametrize("name", ["z.splat", "z.ply", "z.csgs", "cameras.json", "z.sog"])
def test_a_symlink_to_dev_zero_is_refused_naming_the_file(tmp_path, reader, name):
    link = _zero_link(tmp_path, name)
    with pytest.raises(InputError, match="character device, not a regular file") as info:
        READERS[reader](link)
    assert info.value.file == str(link)


@pytest.mark.parametrize("reader", sorted(READERS))
def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path, reader):
    fifo = _fifo(tmp_path, "scene.ply")
    with pytest.raises(InputError, match="FIFO") as info:
        READERS[reader](fifo)
    assert info.value.file == str(fifo)


@pytest.mark.parametrize("reader", ["read_ply", "MappedPly", "read_anchor_ply", "read_regular",
                                    "Decoder.decode"])
def test_a_folder_given_as_a_file_is_refused(tmp_path, reader):
    with pytest.raises(InputError, match="a directory, not a regular file") as info:
        READERS[reader](tmp_path)
    assert info.value.file == str(tmp_path)


def test_a_sog_folder_whose_image_is_a_device_is_refused(tmp_path):
    folder = tmp_path / "scene_sog"
    folder.mkdir()
    for member in (FORMATS / "donut_sh0_sog").iterdir():
        (folder / member.name).write_bytes(member.read_bytes())
    (folder / "means_l.webp").unlink()
    _zero_link(folder, "means_l.webp")
    with pytest.raises(InputError, match="character device") as info:
        read_sog(folder)
    assert info.value.file == str(folder / "means_l.webp")


def test_a_sog_meta_json_fifo_is_refused(tmp_path):
    folder = tmp_path / "scene_sog"
    folder.mkdir()
    _fifo(folder, "meta.json")
    with pytest.raises(InputError, match="FIFO"):
        read_sog(folder)


def test_colmap_files_that_are_devices_are_refused(tmp_path):
    (tmp_path / "cameras.txt").write_text((CAMERAS / "colmap_text" / "cameras.txt").read_text())
    _zero_link(tmp_path, "images.txt")
    # A device is not a COLMAP file: the model is incomplete, said as such, nothing read.
    with pytest.raises(InputError, match="no COLMAP cameras"):
        load_colmap_cameras(tmp_path / "cameras.txt")
    with pytest.raises(InputError, match="character device"):
        load_colmap_cameras(tmp_path / "images.txt")


def test_a_symlink_to_a_regular_file_reads_as_that_file(tmp_path):
    link = tmp_path / "linked.splat"
    link.symlink_to(FORMATS / "donut_sh0.splat")
    assert len(read_scene(link)) == len(read_scene(FORMATS / "donut_sh0.splat")) == 300
    cameras = tmp_path / "cameras.json"
    cameras.symlink_to(CAMERAS / "inria_cameras.json")
    assert len(load_cameras(cameras)) == len(load_cameras(CAMERAS / "inria_cameras.json"))


def test_read_regular_refuses_a_file_above_its_limit(tmp_path):
    path = tmp_path / "big.json"
    path.write_bytes(b" " * 101)
    with pytest.raises(InputError, match="101 bytes, more than the 100") as info:
        read_regular(path, 100, what="a camera file")
    assert info.value.file == str(path)
    assert read_regular(path, 101) == b" " * 101


def _csgs(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "csgs_cli.main", *args], capture_output=True,
                          text=True, timeout=120, cwd=REPO)


def test_cli_info_on_a_dev_zero_symlink_exits_2_with_one_line(tmp_path):
    link = _zero_link(tmp_path, "z.splat")
    done = _csgs("info", str(link))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines() == [
        f"csgs: error: {link}: a character device, not a regular file: csgs reads only "
        "regular files (a symlink to one is fine)"]


def test_cli_encode_with_dev_zero_cameras_exits_2_with_one_line(tmp_path):
    done = _csgs("encode", str(FORMATS / "donut_sh0.ply"), "-o", str(tmp_path / "y.csgs"),
                 "--cameras", "/dev/zero", "--quiet")
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1].startswith(
        "csgs: error: /dev/zero: a character device, not a regular file")
    assert not (tmp_path / "y.csgs").exists()


@pytest.mark.parametrize("reader", sorted(READERS))
def test_a_path_with_a_nul_byte_is_an_input_error_saying_so(tmp_path, reader):
    path = str(tmp_path / "scene\0.ply")
    with pytest.raises(InputError, match="the path contains a NUL byte") as info:
        READERS[reader](path)
    assert info.value.file == path.replace("\0", "\\0")
