"""Tiles coded in parallel: the same bytes for any worker count and engine, and from a
memory-mapped PLY as from a scene read whole."""

from __future__ import annotations

import numpy as np
import pytest

from csgs_cli.main import main
from csgs_codec import Decoder, Encoder, read_ply
from csgs_codec.codec.parallel import run_jobs
from csgs_codec.codec.tile_encoder import encode_ply_tiled
from csgs_codec.errors import InputError
from csgs_codec.interchange.ply_io import write_ply
from csgs_codec.interchange.ply_mmap import MappedPly
from tests.codec.helpers import random_scene, steps_of


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path = tmp_path_factory.mktemp("par") / "scene.ply"
    write_ply(random_scene(2400, sh_degree=3, seed=7, semantic=2, labels=True), path)
    return path


@pytest.fixture(scope="module")
def serial(ply):
    return Encoder(quality=5, hyperprior=False, tile_size=600).encode(read_ply(ply))


def test_local_workers_write_the_same_bytes(ply, serial):
    done = []
    encoder = Encoder(quality=5, hyperprior=False, tile_size=600, workers=2,
                      progress=steps_of("tiles", done))
    assert encoder.encode(read_ply(ply)) == serial
    assert done[-1] == (4, 4)


def test_memory_mapped_ply_writes_the_same_bytes(ply, serial):
    result = encode_ply_tiled(Encoder(quality=5, hyperprior=False, tile_size=600), str(ply))
    assert result.data == serial and result.reconstruction is None
    assert np.array_equal(np.sort(result.order), np.arange(2400))
    mapped = MappedPly(ply)
    rows = np.array([3, 50, 2399])
    assert mapped.scene(rows).equals(read_ply(ply).subset(rows))
    assert np.array_equal(mapped.positions(), read_ply(ply).positions)


def test_cli_streams_a_tiled_ply_to_the_same_bytes(ply, serial, tmp_path):
    out = tmp_path / "s.csgs"
    assert main(["encode", str(ply), "-o", str(out), "--tile-size", "600", "--quality", "5",
                 "--no-hyperprior", "--workers", "2", "--quiet"]) == 0
    assert out.read_bytes() == serial
    assert len(Decoder().decode(out)) == 2400


def test_a_tiled_ply_names_the_properties_it_drops_once(ply, serial, tmp_path):
    """A property the scene does not keep (here 'foo') is said once, as a whole read says
    it, not per tile and not never."""
    import warnings

    from plyfile import PlyData, PlyElement

    from csgs_codec.errors import CsgsWarning

    rows = PlyData.read(str(ply))["vertex"].data
    extended = np.empty(len(rows), dtype=rows.dtype.descr + [("foo", "<f4")])
    for name in rows.dtype.names:
        extended[name] = rows[name]
    extended["foo"] = 1.5
    path = tmp_path / "foo.ply"
    PlyData([PlyElement.describe(extended, "vertex")]).write(str(path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = encode_ply_tiled(Encoder(quality=5, hyperprior=False, tile_size=600),
                                  str(path))
    said = [str(w.message) for w in caught if issubclass(w.category, CsgsWarning)]
    assert said == [f"{path}: ignoring unknown PLY properties: foo"]
    assert result.data == serial


def test_mapped_ply_errors_name_the_file_row(tmp_path):
    scene = random_scene(300, seed=1)
    scene.scales[123, 1] = 200.0  # a log-scale the format refuses
    path = tmp_path / "bad.ply"
    write_ply(scene, path)
    with pytest.raises(InputError) as err:
        encode_ply_tiled(Encoder(hyperprior=False, tile_size=100), str(path))
    assert err.value.index == 123 and err.value.property == "scale_1"
    path.write_bytes(path.read_bytes()[:-5])
    with pytest.raises(InputError, match="declares"):
        MappedPly(path)


def _square(x: int) -> int:
    return x * x


def test_run_jobs_keeps_job_order():
    assert run_jobs(_square, list(range(7)), workers=2) == [x * x for x in range(7)]
    assert run_jobs(_square, [], workers=3) == []


def _thread_settings(_: int) -> tuple[str | None, ...]:
    import os

    from csgs_codec.codec.parallel import THREAD_VARIABLES

    return tuple(os.environ.get(name) for name in THREAD_VARIABLES)


def test_local_workers_run_numeric_libraries_on_one_thread(monkeypatch):
    """Two workers with two BLAS threads each on two cores spin against each other; a
    variable the user set is kept, and this process's environment is left as it was."""
    from csgs_codec.codec.parallel import THREAD_VARIABLES

    for name in THREAD_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("MKL_NUM_THREADS", "3")
    seen = run_jobs(_thread_settings, [0, 1], workers=2)
    expected = tuple("3" if name == "MKL_NUM_THREADS" else "1" for name in THREAD_VARIABLES)
    assert seen == [expected, expected]
    assert _thread_settings(0) == tuple("3" if name == "MKL_NUM_THREADS" else None
                                        for name in THREAD_VARIABLES)


@pytest.mark.slow  # starting a local Ray cluster takes 7-10 s
def test_ray_local_cluster_writes_the_same_bytes(ply, serial):
    pytest.importorskip("ray")
    encoder = Encoder(quality=5, hyperprior=False, tile_size=600, workers=2, ray="local")
    assert encoder.encode(read_ply(ply)) == serial
