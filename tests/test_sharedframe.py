"""raybench.cluster.sharedframe in one process (it plays the worker too): blocks kept
from frame to frame, never lent while a frame over them is held, and no name
left in /dev/shm."""

import gc
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from raybench.cluster import sharedframe

pytestmark = pytest.mark.skipif(not Path(sharedframe.SHM_DIR).is_dir(), reason="no /dev/shm (not Linux)")


def ours() -> set[str]:
    return {p.name for p in Path(sharedframe.SHM_DIR).glob(f"{sharedframe.PREFIX}{os.getpid()}-*")}


@pytest.fixture
def pool():
    sharedframe.forget()
    pool = sharedframe.Pool()
    yield pool
    pool.close()
    sharedframe.forget()
    gc.collect()
    assert not ours(), "a block's name was left in /dev/shm"


def rows(rng, n, width):
    return rng.integers(0, 256, (n, width, 3), dtype=np.uint8), rng.integers(-1, 99, (n, width), dtype=np.int32)


def test_a_frame_written_then_its_name_gone(pool, rng):
    lease = pool.lease(24, 16)
    image, hits = rows(rng, 8, 24)
    assert sharedframe.write_rows(lease.address, 8, image, hits)
    np.testing.assert_array_equal(lease.image[8:], image)
    np.testing.assert_array_equal(lease.hits[8:], hits)
    lease.end()
    assert not sharedframe.write_rows(lease.address, 0, image, hits)  # a late task finds no block
    assert len(ours()) == 1  # the block waits under a name of its own


def test_dropped_frames_reuse_one_block_and_one_mapping(pool, rng):
    for _ in range(4):
        lease = pool.lease(32, 8)
        assert sharedframe.write_rows(lease.address, 0, *rows(rng, 8, 32))
        lease.end()
        del lease
    assert pool.made == 1 and pool.idle == 1 and sharedframe.mapped_blocks() == 1


def test_a_held_frame_is_never_lent_again(pool, rng):
    first = pool.lease(32, 8)
    image, hits = rows(rng, 8, 32)
    sharedframe.write_rows(first.address, 0, image, hits)
    first.end()
    held = first.image[2:5]  # a view of the frame is enough to hold it
    del first
    second = pool.lease(32, 8)
    sharedframe.write_rows(second.address, 0, *rows(rng, 8, 32))
    second.end()
    assert pool.made == 2
    np.testing.assert_array_equal(held, image[2:5])
    del second
    third = pool.lease(32, 8)  # the second's block, back in the pool
    assert pool.made == 2
    third.end()
    del held, third
    gc.collect()
    assert pool.idle == 2  # both back; no more than KEEP_BLOCKS kept
    for lease in [pool.lease(32, 8) for _ in range(3)]:  # three held at once: a third block
        lease.end()
    del lease
    assert pool.made == 3 and pool.idle == sharedframe.KEEP_BLOCKS and len(ours()) == sharedframe.KEEP_BLOCKS


def test_another_size_lets_the_old_blocks_go(pool):
    pool.lease(32, 8).end()
    pool.lease(16, 16).end()
    assert pool.made == 2 and pool.idle == 1 and len(ours()) == 1


def test_a_failed_frames_block_is_not_lent_again(pool):
    lease = pool.lease(32, 8)
    lease.end(ok=False)
    assert not ours()  # its name goes at once
    del lease
    pool.lease(32, 8).end()
    assert pool.made == 2


def test_close_removes_every_name_and_held_frames_stay(pool, rng):
    lease = pool.lease(32, 8)
    image, hits = rows(rng, 8, 32)
    sharedframe.write_rows(lease.address, 0, image, hits)
    lease.end()
    pool.lease(32, 8).end()  # a second block, idle
    assert len(ours()) == 2
    pool.close()
    assert not ours()
    np.testing.assert_array_equal(lease.image, image)
    with pytest.raises(ValueError, match="closed"):
        pool.lease(32, 8)


def test_a_worker_keeps_at_most_two_mappings(pool, rng):
    leases = [pool.lease(32, 8) for _ in range(3)]  # three held frames: three blocks
    for lease in leases:
        assert sharedframe.write_rows(lease.address, 0, *rows(rng, 8, 32))
        lease.end()
    assert sharedframe.mapped_blocks() == sharedframe.KEEP_BLOCKS
    assert sharedframe.forget() == sharedframe.KEEP_BLOCKS and not sharedframe.mapped_blocks()


def test_no_room_no_block(pool, monkeypatch):
    monkeypatch.setattr(sharedframe, "room", lambda size: False)
    assert pool.lease(32, 8) is None and pool.made == 0


def test_a_process_that_never_closes_its_pool_leaves_nothing(tmp_path):
    script = (
        "import os, sys; from raybench.cluster import sharedframe\n"
        "pool = sharedframe.Pool(); lease = pool.lease(32, 8); lease.end(); kept = pool.lease(32, 8)\n"
        "print(os.getpid()); sys.stdout.flush()\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    pid = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True, timeout=300
    ).stdout
    assert not list(Path(sharedframe.SHM_DIR).glob(f"{sharedframe.PREFIX}{pid.strip()}-*"))


def test_a_killed_clients_block_is_removed_by_the_next_and_a_live_ones_kept(pool):
    """SIGKILL of a client mid-frame leaves its block (nothing of it runs
    again); the next client's first block removes it. A live process's
    block (this one's) is left alone."""
    killed = (
        "import os, signal; from raybench.cluster import sharedframe\n"
        "lease = sharedframe.Pool().lease(64, 32)\n"
        "print(os.getpid(), flush=True); os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run([sys.executable, "-c", killed], env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == -9
    left = list(Path(sharedframe.SHM_DIR).glob(f"{sharedframe.PREFIX}{done.stdout.strip()}-*"))
    assert len(left) == 1  # what the kill leaks
    live = pool.lease(16, 8)  # this process's: alive
    nxt = "from raybench.cluster import sharedframe; sharedframe.Pool().lease(16, 8).end()"
    subprocess.run([sys.executable, "-c", nxt], env=env, capture_output=True, timeout=120, check=True)
    assert not left[0].exists()
    assert Path(sharedframe.SHM_DIR, live.name).exists()
    live.end()
