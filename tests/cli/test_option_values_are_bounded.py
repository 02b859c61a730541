"""Option values out of any sane range end in one line naming the option, exit 2 (issue
#52, item 8): huge step counts and seeds (ValueError and overflow tracebacks), a margin of
1e300 (blamed on "property 'features'"), orbits of 10^8 views (minutes of work) and a
JavaScript decoder asked for 100,000 threads (13 GB)."""

from __future__ import annotations

import subprocess

import pytest

from benchmarks._js_receiver import CLI, REPO, node_executable
from csgs_cli.main import main
from csgs_cli.view_options import MAX_ORBIT_VIEWS
from csgs_codec.interchange.ply_io import write_ply
from tests.codec.helpers import random_scene

HUGE = "100000000000000000000"  # 1e20 as an integer


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bounds")
    assert main(["synthetic", str(folder / "data"), "--views", "2", "--size", "16x12",
                 "--gaussians", "10", "--objects", "1", "-q"]) == 0
    scene = folder / "scene.ply"
    write_ply(random_scene(16, sh_degree=0), scene)
    return folder, scene


def _exit_2_naming(argv, option, capsys):
    assert main([*argv, "-q"]) == 2
    err = capsys.readouterr().err
    assert option in err and err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize("option, value", [("--iterations", HUGE), ("--seed", HUGE),
                                           ("--seed", "-1"), ("--margin", "1e300")])
def test_segment_names_the_option(files, capsys, option, value):
    folder, scene = files
    _exit_2_naming(["segment", str(scene), "--images", str(folder / "data"), "-o",
                    str(folder / "o.ply"), option, value], option, capsys)
    assert not (folder / "o.ply").exists()


@pytest.mark.parametrize("option, value", [("--iterations", HUGE),
                                           ("--semantic-iterations", HUGE),
                                           ("--semantic-margin", "1e300")])
def test_train_names_the_option(files, capsys, option, value):
    folder, _ = files
    _exit_2_naming(["train", str(folder / "data"), "-o", str(folder / "x.csgs"), option,
                    value], option.lstrip("-"), capsys)


@pytest.mark.parametrize("argv", [
    ["render", "{scene}", "--orbit", str(MAX_ORBIT_VIEWS + 1), "-o", "{dir}/r"],
    ["render", "{scene}", "--orbit", "100000000", "-o", "{dir}/r"],
    ["select", "{scene}", "--view", "orbit:0", "--orbit", "100000000", "--click", "1,1",
     "-o", "{dir}/s.ply"],
])
def test_an_orbit_of_too_many_views_is_refused(files, capsys, argv):
    folder, scene = files
    _exit_2_naming([w.format(dir=folder, scene=scene) for w in argv], "--orbit", capsys)


@pytest.mark.skipif(node_executable() is None, reason="node is not on PATH")
@pytest.mark.parametrize("threads", ["257", "100000"])
def test_the_js_decoder_bounds_its_threads(threads):
    scene = REPO / "spec" / "vectors" / "scenes" / "color_prior_q3.csgs"
    done = subprocess.run([node_executable(), str(CLI), str(scene), "--threads", threads],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and done.stdout == ""
    assert "--threads must be a whole number 1..256" in done.stderr
    assert len(done.stderr.splitlines()) == 1
