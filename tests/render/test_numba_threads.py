"""The numba kernels can be called from several Python threads at once.

numba's workqueue pool, which csgs_codec.render.numba_threads selects, aborts the whole
process when two threads launch parallel kernels together; the kernels take turns instead.
The check runs in a child process, since the failure it guards against kills its process.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from csgs_codec.render.numba_loader import numba_available

REPO = Path(__file__).resolve().parents[2]

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


@pytest.mark.skipif(not numba_available(), reason="numba not installed")
def test_renders_and_ssim_on_several_threads_match_one_thread():
    done = subprocess.run([sys.executable, "-c", _THREADS_RENDER_AND_SCORE], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == "failures 0 same True", done.stderr[-3000:]
