"""`csgs encode --order-out order.npy`: the decoded order as an int64 .npy, so per-Gaussian
data of the input file lines up with the decoded scene as ``data[order]`` (issue #55 item
5.3); the file the order names is refused as an output like any input."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec.codec.decoder import Decoder
from csgs_codec.interchange.ply_io import read_ply, write_ply
from tests.codec.helpers import random_scene
from tests.codec.test_encode_order import check_order


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path = tmp_path_factory.mktemp("order") / "scene.ply"
    write_ply(random_scene(2000, sh_degree=0, labels=True, seed=4), path)
    return path


@pytest.mark.parametrize("extra", [[], ["--tile-size", "500"], ["--prune-opacity", "0.3"],
                                   ["--tile-size", "500", "--prune-opacity", "0.3"]],
                         ids=["whole", "tiled-streamed", "pruned", "tiled-pruned"])
def test_order_out_lines_the_input_rows_up_with_the_decoded_scene(ply, tmp_path, extra):
    out, order_file = tmp_path / "scene.csgs", tmp_path / "order.npy"
    assert main(["encode", "-q", str(ply), "-o", str(out), "--quality", "3", "--order-out",
                 str(order_file), "--no-hyperprior", *extra]) == 0
    order = np.load(order_file, allow_pickle=False)
    decoded = Decoder().decode(out.read_bytes(), layers="color,semantic")
    prune = float(extra[-1]) if "--prune-opacity" in extra else None
    check_order(read_ply(ply), order, decoded, 3, prune)


@pytest.mark.parametrize("target", ["scene", "output"])
def test_order_out_refuses_to_replace_the_scene_or_the_csgs(ply, tmp_path, capsys, target):
    out = tmp_path / "scene.csgs"
    order_file = ply if target == "scene" else out
    before = ply.read_bytes()
    assert main(["encode", "-q", str(ply), "-o", str(out), "--order-out",
                 str(order_file)]) == 2
    err = capsys.readouterr().err
    assert "--order-out" in err and len(err.strip().splitlines()) == 1
    assert ply.read_bytes() == before and not out.exists()


def test_order_out_refuses_sanitize(ply, tmp_path, capsys):
    assert main(["encode", "-q", str(ply), "-o", str(tmp_path / "s.csgs"), "--sanitize",
                 "--order-out", str(tmp_path / "o.npy")]) == 2
    assert "--sanitize" in capsys.readouterr().err
    assert not (tmp_path / "o.npy").exists()
