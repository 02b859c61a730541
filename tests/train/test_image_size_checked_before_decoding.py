"""Training images and masks: the size in the file's header is checked before any pixel is
decoded (issue #52, item 3). A 244 KB PNG claiming 12000x7000 for a 40x30 view reached 4 GB;
here the files are headers with no pixel data at all, so a reader that decoded first would
fail on the missing data instead of naming the size."""

from __future__ import annotations

import struct
import zlib

import pytest

from csgs_cli.main import main
from csgs_codec.errors import InputError
from csgs_codec.train.datasets import load_dataset
from csgs_codec.train.image_files import MAX_IMAGE_PIXELS, read_image, read_mask
from csgs_codec.train.synthetic import make_synthetic_dataset, write_transforms_dataset


def png_header_only(width: int, height: int, colour_type: int = 0) -> bytes:
    """A PNG signature, an IHDR claiming ``width`` x ``height`` 8-bit pixels and IEND: no
    pixel data."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data)))

    ihdr = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


@pytest.fixture(scope="module")
def synthetic():
    return make_synthetic_dataset(3, objects=2, gaussians_per_object=30, views=2, width=40,
                                  height=30)


def test_a_huge_mask_for_a_small_view_is_refused_by_its_header(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    mask = next((tmp_path / "masks").glob("*.png"))
    mask.write_bytes(png_header_only(12000, 7000))
    with pytest.raises(InputError,
                       match=r"mask is 12000x7000 but its image .*view_001.png is 40x30") as err:
        load_dataset(tmp_path)
    assert err.value.file == str(mask)


def test_a_huge_image_for_a_small_camera_is_refused_by_its_header(tmp_path, synthetic):
    write_transforms_dataset(synthetic.views, tmp_path)
    image = next((tmp_path / "images").glob("*.png"))
    image.write_bytes(png_header_only(12000, 7000, colour_type=2))
    with pytest.raises(InputError, match=r"image is 12000x7000 but its camera is 40x30"):
        load_dataset(tmp_path)


def test_the_cli_names_the_mask_and_exits_2(tmp_path, synthetic, capsys):
    write_transforms_dataset(synthetic.views, tmp_path)
    mask = next((tmp_path / "masks").glob("*.png"))
    mask.write_bytes(png_header_only(12000, 7000))
    assert main(["train", str(tmp_path), "-o", str(tmp_path / "x.csgs"), "-q"]) == 2
    err = capsys.readouterr().err
    assert str(mask) in err and "12000x7000" in err and err.count("\n") == 1


def test_an_image_over_the_pixel_bound_is_refused_without_a_size_to_match(tmp_path):
    side = 12000  # under Pillow's own bomb limit (1.8e8 pixels), over csgs's
    assert side * side > MAX_IMAGE_PIXELS
    path = tmp_path / "big.png"
    path.write_bytes(png_header_only(side, side))
    for reader in (read_image, read_mask):
        with pytest.raises(InputError, match="more than the"):
            reader(path)
