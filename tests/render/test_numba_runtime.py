"""How the numba kernels run: from several Python threads at once, and on an install where
numba has nowhere to cache them.

numba's workqueue pool, which csgs_codec.render.numba_runtime selects, aborts the whole
process when two threads launch parallel kernels together; the kernels take turns instead.
That check runs in a child process, since the failure it guards against kills its process.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import textwrap
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

from csgs_codec.render.numba_loader import numba_available

REPO = Path(__file__).resolve().parents[2]
needs_numba = pytest.mark.skipif(not numba_available(), reason="numba not installed")

_THREADS_RENDER_AND_SCORE = textwrap.dedent("""
    import threading
    import numpy as np
    import torch
    from csgs_codec.interchange.ply_io import read_ply
    from csgs_codec.metrics.ssim import ssim
    from csgs_codec.render.rasterizer import render
    from csgs_codec.scene.orbit import orbit_cameras

    scene = read_ply("samples/donut.ply")
    scene = scene.subset(np.arange(0, len(scene), 8))
    cameras = orbit_cameras(scene, 4, width=96, height=72)

    def work(i):
        image = render(scene, cameras[i], backend="numba").image
        a = torch.from_numpy(np.ascontiguousarray(image[..., :3])).requires_grad_(True)
        b = torch.from_numpy(np.ascontiguousarray(image[::-1, :, :3]))
        score = ssim(a, b, kernel="auto")
        score.backward()
        return image, float(score), a.grad.numpy().copy()

    alone = [work(i) for i in range(4)]
    together, failures = [None] * 8, []

    def run(k):
        try:
            together[k] = work(k % 4)
        except BaseException as exc:
            failures.append(repr(exc))

    threads = [threading.Thread(target=run, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    same = all(np.array_equal(got[0], alone[k % 4][0]) and got[1] == alone[k % 4][1]
               and np.array_equal(got[2], alone[k % 4][2])
               for k, got in enumerate(together) if got is not None)
    print("failures", len(failures), "same", same)
""")


@needs_numba
def test_renders_and_ssim_on_several_threads_match_one_thread():
    done = subprocess.run([sys.executable, "-c", _THREADS_RENDER_AND_SCORE], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == "failures 0 same True", done.stderr[-3000:]


@needs_numba
def test_a_kernel_numba_cannot_cache_compiles_uncached_with_one_warning(monkeypatch):
    from csgs_codec.errors import CsgsWarning
    from csgs_codec.render import numba_runtime

    monkeypatch.setattr(numba_runtime, "_warned_no_cache", False)
    # numba has no cache folder for code compiled from a string: the same refusal as a
    # read-only install with no writable home.
    namespace: dict = {}
    exec(compile("def twice(a):\n    return a * 2\n", "<no file>", "exec"), namespace)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        first = numba_runtime.jit_kernel()(namespace["twice"])
        second = numba_runtime.jit_kernel(parallel=False)(namespace["twice"])
    assert first(np.arange(3.0)).tolist() == [0.0, 2.0, 4.0]
    assert second(np.int64(21)) == 42
    assert [type(w.message) for w in caught] == [CsgsWarning]
    assert "NUMBA_CACHE_DIR" in str(caught[0].message)


def _read_only_mounts_work() -> bool:
    if shutil.which("unshare") is None or os.geteuid() != 0:
        return False
    probe = subprocess.run(["unshare", "--mount", "true"], capture_output=True)
    return probe.returncode == 0


@pytest.mark.slow  # every kernel is compiled again, with no cache: about a minute
@needs_numba
@pytest.mark.skipif(not _read_only_mounts_work(), reason="needs root and unshare --mount")
def test_encode_from_a_read_only_install_with_no_writable_home(tmp_path):
    """`csgs encode` of an SH scene (its step allocation renders with the kernels) from a
    package on a read-only file system, HOME read-only too: the file numba's caching would
    make, after one warning, not a traceback."""
    from csgs_codec import Encoder
    from csgs_codec.interchange.ply_io import read_ply, write_ply

    capture = read_ply(REPO / "benchmarks" / "data" / "yashica_t4_top8192.ply")
    source = tmp_path / "capture.ply"
    write_ply(capture.subset(np.arange(0, len(capture), 8)), source)
    expected = hashlib.sha256(Encoder().encode(read_ply(source))).hexdigest()
    home = tmp_path / "home"
    home.mkdir()
    out = tmp_path / "out.csgs"
    script = (f"mount --bind -o ro {REPO} {REPO} && mount --bind -o ro {home} {home} && "
              f"HOME={home} XDG_CACHE_HOME={home}/.cache {sys.executable} -m csgs_cli.main "
              f"encode {source} -o {out}")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    done = subprocess.run(["unshare", "--mount", "bash", "-c", script], cwd=tmp_path,
                          capture_output=True, text=True, timeout=900, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "Traceback" not in done.stderr
    assert "NUMBA_CACHE_DIR" in done.stderr
    assert hashlib.sha256(out.read_bytes()).hexdigest() == expected


def _one_kernel_launch() -> None:
    from csgs_codec.render import numba_kernels

    ids = np.array([0, 1, 1], np.int64)
    total = numba_kernels.sum_slots(ids, np.ones((3, 2), np.float32), 2)
    assert total.tolist() == [[1.0, 1.0], [2.0, 2.0]]


@needs_numba
def test_a_child_forked_while_a_thread_has_the_turn_can_launch_kernels():
    from csgs_codec.render import numba_runtime
    from tests.fork_while_held import child_finishes_while_a_thread_holds

    _one_kernel_launch()  # compiled (or loaded) before the fork, as in a real service
    code = child_finishes_while_a_thread_holds(lambda: numba_runtime._LAUNCH,
                                               _one_kernel_launch)
    assert code == 0, "the child waited for a turn no thread of its own held"


_HOLD_THE_CACHE_LOCK = textwrap.dedent("""
    import fcntl, sys
    from csgs_codec.render.numba_runtime import cache_lock_path
    with open(cache_lock_path(), "a+b") as handle:
        fcntl.lockf(handle, fcntl.LOCK_EX)
        print("held", flush=True)
        sys.stdin.readline()
""")

_FIRST_LAUNCH = textwrap.dedent("""
    import sys
    import numpy as np
    from csgs_codec.render import numba_kernels
    ids = np.array([0, 1, 1], np.int64)
    print("ready", flush=True)
    total = numba_kernels.sum_slots(ids, np.ones((3, 2), np.float32), 2)
    print("first", total.tolist(), flush=True)
""")


def _holder() -> subprocess.Popen:
    holder = subprocess.Popen([sys.executable, "-c", _HOLD_THE_CACHE_LOCK], cwd=REPO,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    return holder


@needs_numba
@pytest.mark.skipif(not hasattr(os, "fork"), reason="POSIX record locks")
def test_a_first_launch_waits_while_another_process_writes_the_cache():
    """numba's cache is unsafe against concurrent writers (CI's parallel workers crashed on
    what they wrote together): a process's first launch waits for the one holding the lock,
    although the kernel is cached already (loading it alone takes a fraction of a second)."""
    _one_kernel_launch()  # cached by this process, so the child only loads it
    holder = _holder()
    user = subprocess.Popen([sys.executable, "-c", _FIRST_LAUNCH], cwd=REPO,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert user.stdout.readline().strip() == "ready"
        with pytest.raises(subprocess.TimeoutExpired):
            user.wait(timeout=3.0)  # blocked on the lock, not finished
    finally:
        holder.communicate("\n", timeout=30)
    out, err = user.communicate(timeout=300)
    assert user.returncode == 0, err[-2000:]
    assert out.strip() == "first [[1.0, 1.0], [2.0, 2.0]]"


@needs_numba
@pytest.mark.skipif(not hasattr(os, "fork"), reason="POSIX record locks")
def test_later_launches_of_the_same_types_take_no_cache_lock():
    from csgs_codec.render import numba_kernels

    _one_kernel_launch()  # the first launch of these types in this process
    holder = _holder()
    try:
        finished = threading.Event()

        def launch() -> None:
            _one_kernel_launch()
            finished.set()

        worker = threading.Thread(target=launch, daemon=True)
        worker.start()
        assert finished.wait(60), "a second launch waited for the cache lock"
        ids = np.array([0, 0], np.int32)  # a new argument type: this one must wait
        late = threading.Thread(target=numba_kernels.sum_slots,
                                args=(ids, np.ones((2, 1), np.float32), 1), daemon=True)
        late.start()
        late.join(1.0)
        assert late.is_alive()
    finally:
        holder.communicate("\n", timeout=30)
    late.join(120)
    assert not late.is_alive()
