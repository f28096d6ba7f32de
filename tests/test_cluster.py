"""raybench.cluster on a real Dask cluster: one LocalCluster-like embedded
cluster of 2 worker processes (raybench's own, 127.0.0.1 only), shared by
the module's tests; each result is checked against the same work done in
this one process."""

import contextlib
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil
import pytest
from conftest import sigint_default
from PIL import Image

import raybench
import raybench.gif
from raybench import Camera, RaybenchError, camera_path, cluster, host, sequence
from raybench.bench import machines
from raybench.cli import run
from raybench.cluster import sharedframe, tasks, work

pytest.importorskip("distributed")

SIZES = [(64, 48), (40, 56), (72, 40)]


@pytest.fixture(scope="module")
def running():
    # Compiled here first, into the disk cache, so that the workers load the
    # kernels rather than compile them each (raybench.compiled).
    for accel in ("bvh", "none"):
        raybench.render(raybench.random_spheres(3), width=16, height=8, device="cpu", accel=accel)
    with cluster.Cluster(workers=2, device="cpu") as c:
        c.client.wait_for_workers(2, timeout=120)
        yield c
    # the client's kept frame memory went with the cluster: nothing of this process is left in /dev/shm
    assert not [name for name in blocks() if name.startswith(f"{sharedframe.PREFIX}{os.getpid()}-")]


def scene_and_camera(rng, n=None):
    scene = raybench.random_spheres(int(n or rng.integers(1, 60)), seed=int(rng.integers(2**31)))
    camera = Camera(position=tuple(rng.uniform(-0.3, 0.3, 3)), look_at=tuple(rng.uniform(-0.2, 0.2, 3) + (0, 0, 3)))
    return scene, camera


def scene_with_hits_and_misses(rng, width, height, accel="bvh"):
    """A random scene and camera whose frame has hits and misses both, so a
    comparison covers both kinds of pixel (a few spheres near the camera can
    fill the frame), with that single-process frame."""
    for _ in range(20):
        scene, camera = scene_and_camera(rng)
        whole = raybench.render(scene, camera, width, height, device="cpu", accel=accel)
        if (whole.hits >= 0).any() and (whole.hits < 0).any():
            break
    return scene, camera, whole


def png(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def test_everything_listens_on_loopback_only(running):
    info = running.client.scheduler_info(n_workers=-1)
    assert info["address"].startswith("tls://127.0.0.1:")
    assert len(info["workers"]) == 2
    for address, worker in info["workers"].items():
        assert address.startswith("tls://127.0.0.1:")
        assert worker["nanny"].startswith("tls://127.0.0.1:")
    pids = [os.getpid(), *running.client.run(os.getpid).values()]
    pids += [psutil.Process(p).ppid() for p in pids[1:]]  # the nannies
    listening = [c for p in set(pids) for c in psutil.Process(p).net_connections("inet") if c.status == "LISTEN"]
    assert len(listening) >= 4  # the scheduler's, the workers' and the nannies' at least
    assert {c.laddr.ip for c in listening} == {"127.0.0.1"}


def outsider_gets_in(address: str, security) -> bool:
    """Whether a connection to address with security's credentials (None:
    none, plain TCP to the same port) gets through Dask's handshake, within 10 s."""
    import asyncio

    from distributed.comm import connect

    async def attempt():
        if security is None:
            comm = await connect("tcp://" + address.split("://", 1)[1], timeout=5)
        else:
            comm = await connect(address, timeout=5, **security.get_connection_args("client"))
        try:  # a request the scheduler and every worker answers
            await comm.write({"op": "identity", "reply": True})
            return isinstance(await asyncio.wait_for(comm.read(), 5), dict)
        finally:
            comm.abort()

    try:
        return asyncio.run(asyncio.wait_for(attempt(), 10))
    except (OSError, TimeoutError, EOFError):  # distributed's CommClosedError is an OSError
        return False


def test_an_outsider_cannot_connect_to_the_embedded_cluster(running):
    """Every port of the embedded cluster (scheduler, workers, nannies) takes
    only the cluster's own credentials: plain TCP, or TLS with another key,
    is refused; the cluster's own get in (so the refusals are the credentials')."""
    from distributed.security import Security

    info = running.client.scheduler_info(n_workers=-1)
    addresses = [info["address"], *info["workers"], *(w["nanny"] for w in info["workers"].values())]
    assert len(addresses) == 5
    stranger = Security.temporary()  # a valid TLS client, signed by a CA of its own
    for address in addresses:
        assert not outsider_gets_in(address, None), address
        assert not outsider_gets_in(address, stranger), address
        assert outsider_gets_in(address, running.cluster.security), address
    from distributed import Client

    with pytest.raises((OSError, TimeoutError)):
        Client(info["address"], security=stranger, timeout=3)


def test_workers_split_the_cores_and_go_without_dask_malloc_setting(running):
    env = running.client.run(lambda: (os.environ.get("NUMBA_NUM_THREADS"), os.environ.get("MALLOC_TRIM_THRESHOLD_")))
    assert set(env.values()) == {(str(max(1, host.usable_cores() // 2)), None)}


@pytest.mark.parametrize("accel", ["bvh", "none"])
def test_tiles_are_the_single_process_frame_bit_for_bit(running, rng, accel):
    width, height = SIZES[rng.integers(len(SIZES))]
    rows = 8 * int(rng.integers(1, 4))
    scene, camera, whole = scene_with_hits_and_misses(rng, width, height, accel)
    frame = cluster.render(running.client, scene, camera, width, height, device="cpu", rows=rows, accel=accel)
    assert frame.image.shape == (height, width, 3) and frame.device == "cpu"
    np.testing.assert_array_equal(frame.image, whole.image)
    np.testing.assert_array_equal(frame.hits, whole.hits)
    assert (frame.hits >= 0).any() and (frame.hits < 0).any()  # hits and misses both compared


def blocks() -> set[str]:
    """raybench's shared-memory blocks in /dev/shm, whoever made them."""
    return {p.name for p in Path("/dev/shm").glob(sharedframe.PREFIX + "*")}


def own_blocks() -> set[str]:
    """This process's blocks: other tests run beside these, and make and drop blocks of their own."""
    return {p.name for p in Path("/dev/shm").glob(f"{sharedframe.PREFIX}{os.getpid()}-*")}


@pytest.fixture
def no_block_left(running):
    """Whatever a test leaves kept for the client's next frames, nothing is
    left in /dev/shm once the client's kept memory is released."""
    before = own_blocks()
    yield
    cluster.release(running.client)
    assert own_blocks() <= before, "a shared-memory block was left in /dev/shm"


def mapped(client) -> list[int]:
    """How many blocks each worker keeps mapped."""
    return sorted(client.run(sharedframe.mapped_blocks).values())


def test_workers_on_this_host_write_into_the_clients_block(running, rng, no_block_left):
    pool = sharedframe.Pool()
    lease = pool.lease(24, 16)
    try:
        image = rng.integers(0, 256, (8, 24, 3), dtype=np.uint8)
        hits = rng.integers(-1, 100, (8, 24), dtype=np.int32)
        wrote = running.client.submit(sharedframe.write_rows, lease.address, 8, image, hits, pure=False).result(
            timeout=120
        )
        assert wrote is True
        np.testing.assert_array_equal(lease.image[8:], image)
        np.testing.assert_array_equal(lease.hits[8:], hits)
        # a block the worker cannot open (as on another host): nothing written, and it says so
        elsewhere = (sharedframe.PREFIX + "elsewhere", 24, 16)
        assert (
            running.client.submit(sharedframe.write_rows, elsewhere, 0, image, hits, pure=False).result(timeout=120)
            is False
        )
    finally:
        lease.end()
        pool.close()
    # the frame is over: a task of it that starts now finds no block
    assert (
        running.client.submit(sharedframe.write_rows, lease.address, 0, image, hits, pure=False).result(timeout=120)
        is False
    )


def test_a_tile_task_on_this_host_sends_no_rows(running, rng, no_block_left):
    """_tile on a worker with the client's block: its rows are in the block, and none come back."""
    scene, camera = scene_and_camera(rng)
    spec = work._spec(40, 24, "cpu", "thesis", None, None, {})
    whole = raybench.render(scene, camera, 40, 24, device="cpu")
    pool = sharedframe.Pool()
    lease = pool.lease(40, 24)
    try:
        task = running.client.submit(tasks._tile, scene, "test-scene", spec, camera, (8, 24), lease.address)
        first, image, hits, _, _ = task.result(timeout=120)
        assert (first, image, hits) == (8, None, None)
        np.testing.assert_array_equal(lease.image[8:], whole.image[8:])
        np.testing.assert_array_equal(lease.hits[8:], whole.hits[8:])
    finally:
        lease.end()
        pool.close()


@pytest.mark.parametrize("path", ["shared", "sent", "sent-by-workers", "no-room"])
def test_shared_and_sent_tiles_are_the_single_process_frame(running, rng, monkeypatch, path, no_block_left):
    """shared: rows written into the client's block; sent: shared=False;
    sent-by-workers: a block the workers cannot open (another host's case),
    so each task falls back to sending its rows; no-room: /dev/shm too full
    for the frame, so no block is made and every tile is sent."""
    cluster.release(running.client)  # no block kept from an earlier test: each path makes its own, or none
    if path == "no-room":
        monkeypatch.setattr(sharedframe, "room", lambda size: False)
    if path == "sent-by-workers":
        monkeypatch.setattr(
            sharedframe.Lease, "address", property(lambda b: (b.name + "-elsewhere", b.width, b.height))
        )
    width, height = SIZES[rng.integers(len(SIZES))]
    scene, camera, whole = scene_with_hits_and_misses(rng, width, height)
    rows = 8 * int(rng.integers(1, 4))
    shared = path != "sent"
    frame = cluster.render(running.client, scene, camera, width, height, device="cpu", rows=rows, shared=shared)
    np.testing.assert_array_equal(frame.image, whole.image)
    np.testing.assert_array_equal(frame.hits, whole.hits)
    assert frame.image.flags.writeable and frame.hits.dtype == np.int32
    assert (frame.hits >= 0).any() and (frame.hits < 0).any()


def test_a_failed_job_leaves_no_block(running, no_block_left):
    with pytest.raises(RaybenchError, match="accel: must be one of"):
        cluster.render(running.client, raybench.random_spheres(3), width=32, height=32, device="cpu", accel="bogus")


def interrupt_after_the_first_tile(monkeypatch) -> None:
    """A Ctrl-C in the middle of a frame: distributed.as_completed gives the
    first finished task, then raises KeyboardInterrupt."""
    import distributed

    as_completed = distributed.as_completed

    def interrupted(tasks):
        yield next(iter(as_completed(tasks)))
        raise KeyboardInterrupt

    monkeypatch.setattr(distributed, "as_completed", interrupted)


def test_ctrl_c_during_a_frame_leaves_no_block(running, monkeypatch, no_block_left):
    interrupt_after_the_first_tile(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        cluster.render(running.client, raybench.random_spheres(3), width=32, height=32, device="cpu", rows=8)


def test_a_frame_outlives_its_block(running, no_block_left):
    """The kept memory released while the frame is held: its name is gone at once; the memory stays the frame's
    until the frame is dropped."""
    scene = raybench.random_spheres(5, seed=1)
    frame = cluster.render(running.client, scene, width=32, height=24, device="cpu", rows=8)
    cluster.release(running.client)
    assert not any(name.startswith(f"{sharedframe.PREFIX}{os.getpid()}-") for name in blocks())
    assert mapped(running.client) == [0, 0]  # the workers let go of their mappings too
    np.testing.assert_array_equal(frame.image, raybench.render(scene, width=32, height=24, device="cpu").image)
    image, hits = frame.image.copy(), frame.hits.copy()
    del frame
    import gc

    gc.collect()
    np.testing.assert_array_equal(image, raybench.render(scene, width=32, height=24, device="cpu").image)
    assert hits.shape == (24, 32)


def test_frames_of_one_size_reuse_one_block(running, rng, no_block_left):
    """Frames dropped in turn: one block made, and each frame is still the single-process one."""
    cluster.release(running.client)
    scene, _ = scene_and_camera(rng, 30)
    for _ in range(3):
        camera = scene_and_camera(rng)[1]
        frame = cluster.render(running.client, scene, camera, 40, 32, device="cpu", rows=8)
        whole = raybench.render(scene, camera, 40, 32, device="cpu")
        np.testing.assert_array_equal(frame.image, whole.image)
        np.testing.assert_array_equal(frame.hits, whole.hits)
        del frame
    pool = work.pool(running.client)
    assert pool.made == 1 and pool.idle == 1
    # between frames the block waits under a name of its own, which no frame's task has
    assert len([n for n in blocks() if n.startswith(f"{sharedframe.PREFIX}{os.getpid()}-")]) == 1
    assert max(mapped(running.client)) == 1  # each worker that wrote kept its one mapping


def test_a_held_frame_is_not_written_by_the_next(running, rng, no_block_left):
    """A frame held while the next is traced keeps its pixels; the two blocks then take turns."""
    cluster.release(running.client)
    scene, _ = scene_and_camera(rng, 30)
    cameras = [scene_and_camera(rng)[1] for _ in range(4)]
    wholes = [raybench.render(scene, c, 48, 24, device="cpu") for c in cameras]
    held = [cluster.render(running.client, scene, cameras[0], 48, 24, device="cpu", rows=8)]
    for n in range(1, 4):
        held.append(cluster.render(running.client, scene, cameras[n], 48, 24, device="cpu", rows=8))
        for frame, whole in zip(held, wholes[n - 1 : n + 1], strict=True):
            np.testing.assert_array_equal(frame.image, whole.image)
            np.testing.assert_array_equal(frame.hits, whole.hits)
        held.pop(0)  # frame = render(...): the one before is let go once the next is made
    assert work.pool(running.client).made == 2


def tile_keys(client) -> int:
    """How many of the client's tiles the scheduler still holds."""
    return client.run_on_scheduler(lambda dask_scheduler: sum("_tile" in str(k) for k in dask_scheduler.tasks))


def settled_tile_keys(client, at_most: int, within_s: float = 30) -> int:
    """tile_keys once it is at most at_most, or when within_s has passed. A release
    travels in the client's batched stream, while run_on_scheduler takes a comm of
    its own, so a query can overtake a release sent just before it."""
    deadline = time.monotonic() + within_s
    while (held := tile_keys(client)) > at_most and time.monotonic() < deadline:
        time.sleep(0.05)
    return held


def test_a_frames_tiles_are_held_only_until_the_next_frames_go(running, rng, no_block_left):
    """The last frame's tiles are let go once the next frame's are submitted
    (so that their release does not go out alone just before them), never
    more than one frame's, and none once the client's frames are released."""
    cluster.release(running.client)
    scene, camera = scene_and_camera(rng, 20)
    tiles = int(rng.integers(2, 6))
    for _ in range(3):
        frame = cluster.render(running.client, scene, camera, 24, 8 * tiles, device="cpu", rows=8)
        assert settled_tile_keys(running.client, tiles) == tiles
        del frame
    cluster.release(running.client)
    assert settled_tile_keys(running.client, 0) == 0


def test_the_workers_devices_are_asked_again_after_a_while_or_a_failure(running, rng, monkeypatch, no_block_left):
    asked = []
    check = work.check_workers
    monkeypatch.setattr(work, "check_workers", lambda *a, **k: asked.append(1) or check(*a, **k))
    cluster.release(running.client)
    scene, camera = scene_and_camera(rng, 10)
    for _ in range(3):
        cluster.render(running.client, scene, camera, 24, 16, device="cpu", rows=8)
    assert len(asked) == 1  # well within WORKERS_FRESH_S
    monkeypatch.setattr(work, "WORKERS_FRESH_S", 0.0)
    for _ in range(2):
        cluster.render(running.client, scene, camera, 24, 16, device="cpu", rows=8)
    assert len(asked) == 3
    monkeypatch.setattr(work, "WORKERS_FRESH_S", 3600.0)
    with pytest.raises(RaybenchError, match="accel: must be one of"):
        cluster.render(running.client, scene, camera, 24, 16, device="cpu", rows=8, accel="bogus")
    cluster.render(running.client, scene, camera, 24, 16, device="cpu", rows=8)
    assert len(asked) == 4  # the failed frame used the answer kept; the next one asked afresh


def test_a_scene_changed_in_place_is_traced_as_changed(running, rng, no_block_left):
    """The scene's key is its hash, taken every frame: spheres moved in place
    between two frames of one Scene object are the next frame's spheres, not
    the workers' kept tree of the old ones."""
    for _ in range(20):
        scene, camera = scene_and_camera(rng, 40)
        first = cluster.render(running.client, scene, camera, 40, 32, device="cpu", rows=8)
        if (first.hits >= 0).sum() > 20:
            break
    seen = np.unique(first.hits[first.hits >= 0])
    scene.spheres[0, seen[: max(1, len(seen) // 2)]] += 1000  # half the spheres in view (one at least), moved out of it
    frame = cluster.render(running.client, scene, camera, 40, 32, device="cpu", rows=8)
    whole = raybench.render(scene, camera, 40, 32, device="cpu")
    np.testing.assert_array_equal(frame.image, whole.image)
    np.testing.assert_array_equal(frame.hits, whole.hits)
    assert not np.array_equal(frame.hits, first.hits)  # the change is in the picture


def test_another_size_gets_its_own_block(running, rng, no_block_left):
    cluster.release(running.client)
    scene, camera = scene_and_camera(rng, 30)
    for width, height in [(40, 24), (56, 16), (40, 24)]:
        frame = cluster.render(running.client, scene, camera, width, height, device="cpu", rows=8)
        whole = raybench.render(scene, camera, width, height, device="cpu")
        np.testing.assert_array_equal(frame.image, whole.image)
        np.testing.assert_array_equal(frame.hits, whole.hits)
        del frame
    pool = work.pool(running.client)
    assert pool.made == 3 and pool.idle == 1  # a size's blocks let go for the next size
    assert len([n for n in blocks() if n.startswith(f"{sharedframe.PREFIX}{os.getpid()}-")]) == 1
    assert max(mapped(running.client)) <= sharedframe.KEEP_BLOCKS


def test_an_interrupted_frames_block_is_not_lent_again(running, monkeypatch, no_block_left):
    cluster.release(running.client)
    scene = raybench.random_spheres(7, seed=3)
    interrupt_after_the_first_tile(monkeypatch)
    with pytest.raises(KeyboardInterrupt):
        cluster.render(running.client, scene, width=32, height=32, device="cpu", rows=8)
    assert not [n for n in blocks() if n.startswith(f"{sharedframe.PREFIX}{os.getpid()}-")]
    monkeypatch.undo()
    frame = cluster.render(running.client, scene, width=32, height=32, device="cpu", rows=8)
    np.testing.assert_array_equal(frame.image, raybench.render(scene, width=32, height=32, device="cpu").image)
    assert work.pool(running.client).made == 2  # a new block, not the one a late task might still write


def test_without_a_block_the_tiles_are_sent(running, rng, monkeypatch, no_block_left):
    """/dev/shm refuses the block (no room for its pages): the tiles are sent, and the frame is the same."""

    def refused(*args):
        raise OSError(28, "No space left on device")

    cluster.release(running.client)
    monkeypatch.setattr(sharedframe.Block, "__init__", refused)
    scene, camera = scene_and_camera(rng)
    frame = cluster.render(running.client, scene, camera, 40, 24, device="cpu", rows=8)
    np.testing.assert_array_equal(frame.image, raybench.render(scene, camera, 40, 24, device="cpu").image)
    assert work.pool(running.client).made == 0


def test_closing_the_cluster_leaves_nothing_in_dev_shm():
    """A cluster of its own, closed with a frame still held: no name left, and the frame stays valid."""
    scene = raybench.random_spheres(9, seed=4)
    with cluster.Cluster(workers=1, device="cpu") as own:
        frame = cluster.render(own.client, scene, width=32, height=16, device="cpu", rows=8)
        assert [n for n in blocks() if n.startswith(f"{sharedframe.PREFIX}{os.getpid()}-")]
    assert not [n for n in blocks() if n.startswith(f"{sharedframe.PREFIX}{os.getpid()}-")]
    np.testing.assert_array_equal(frame.image, raybench.render(scene, width=32, height=16, device="cpu").image)


@pytest.mark.gpu
def test_cuda_tiles_are_the_single_process_frame_bit_for_bit(running, rng):
    """On cuda workers (numba's simulator without a GPU: keep it tiny)."""
    scene, camera = scene_and_camera(rng, 20)
    frame = cluster.render(running.client, scene, camera, 24, 16, device="cuda", rows=8)
    whole = raybench.render(scene, camera, 24, 16, device="cuda")
    assert frame.device == "cuda"
    np.testing.assert_array_equal(frame.image, whole.image)
    np.testing.assert_array_equal(frame.hits, whole.hits)


def test_a_frame_too_large_to_assemble_here_is_refused_before_work(running, monkeypatch):
    monkeypatch.setattr(work, "host_available_bytes", lambda: 64 * 48 * 7 - 1)
    with pytest.raises(RaybenchError, match=r"64x48 .* more than .* on the host \(where the frame is assembled\)"):
        cluster.render(running.client, raybench.random_spheres(3), width=64, height=48, device="cpu")


def test_a_tile_must_be_whole_packets_of_rows(running):
    with pytest.raises(RaybenchError, match="multiple of 8"):
        cluster.render(running.client, raybench.random_spheres(3), width=32, height=32, device="cpu", rows=12)


def test_sequence_is_the_single_process_frames_and_resumes(running, rng, tmp_path):
    scene, camera = scene_and_camera(rng, 20)
    cameras = camera_path.orbit(camera, 6)
    seen = []
    paths = cluster.render_sequence(
        running.client, scene, cameras, tmp_path, 48, 32, device="cpu",
        sequence_options=cluster.SequenceOptions(on_frame=lambda n, p: seen.append(n)),
    )  # fmt: skip
    assert sorted(seen) == list(range(6)) and [p.name for p in paths] == [f"frame_{n:05d}.png" for n in range(6)]
    with raybench.Renderer(scene, 48, 32, device="cpu") as renderer:
        for path, cam in zip(paths, cameras, strict=True):
            np.testing.assert_array_equal(png(path), renderer.render(cam).image)
    # resumption: two frames lost, the others left as they are
    kept = {p: p.stat().st_mtime_ns for p in paths}
    for n in (1, 4):
        paths[n].unlink()
    seen.clear()
    cluster.render_sequence(
        running.client, scene, cameras, tmp_path, 48, 32, device="cpu",
        sequence_options=cluster.SequenceOptions(on_frame=lambda n, p: seen.append(n)),
    )  # fmt: skip
    assert seen[:4] == [0, 2, 3, 5] and sorted(seen[4:]) == [1, 4]
    for n, path in enumerate(paths):
        if n not in (1, 4):
            assert path.stat().st_mtime_ns == kept[path]
    with raybench.Renderer(scene, 48, 32, device="cpu") as renderer:
        for n in (1, 4):
            np.testing.assert_array_equal(png(paths[n]), renderer.render(cameras[n]).image)


def test_sequence_png_level(running, rng, tmp_path):
    """A sequence's frames deflated at render.PNG_LEVEL by default, stored at png_level=0; the same pixels;
    a level out of range refused before any work."""
    scene, camera = scene_and_camera(rng, 20)
    cameras = camera_path.orbit(camera, 2)
    (tmp_path / "default").mkdir()
    (tmp_path / "stored").mkdir()
    default = cluster.render_sequence(running.client, scene, cameras, tmp_path / "default", 48, 32, device="cpu")
    stored = cluster.render_sequence(running.client, scene, cameras, tmp_path / "stored", 48, 32, device="cpu",
                                     sequence_options=cluster.SequenceOptions(png_level=0))  # fmt: skip
    raw = 48 * 32 * 3 + 32  # the pixels and a filter byte a row
    for a, b in zip(default, stored, strict=True):
        np.testing.assert_array_equal(png(a), png(b))
        assert b.stat().st_size > raw > a.stat().st_size
    (tmp_path / "bad").mkdir()
    with pytest.raises(RaybenchError, match="PNG level: must be a whole number 0"):
        cluster.render_sequence(running.client, scene, cameras, tmp_path / "bad", 48, 32, device="cpu",
                                sequence_options=cluster.SequenceOptions(png_level=10))  # fmt: skip
    assert not any((tmp_path / "bad").iterdir())


@pytest.mark.slow
def test_a_worker_killed_mid_sequence_loses_nothing(running, rng, tmp_path):
    scene, camera = scene_and_camera(rng, 200)
    cameras = camera_path.orbit(camera, 24)
    pids = running.client.run(os.getpid)
    victim = sorted(pids.values())[int(rng.integers(2))]
    killed = []

    def on_frame(n, path):
        done = len(list(tmp_path.glob("frame_*.png")))  # frames arrive in any order: count them, not their index
        if not killed and done >= 3:
            os.kill(victim, signal.SIGKILL)
            killed.append(done)

    options = {"accel": "none", "kernel": "simple"}  # slow enough frames that the kill lands mid-sequence
    paths = cluster.render_sequence(
        running.client, scene, cameras, tmp_path, 160, 120, device="cpu",
        sequence_options=cluster.SequenceOptions(frames_per_task=1, on_frame=on_frame), **options,
    )  # fmt: skip
    assert killed and killed[0] < len(cameras)  # killed with frames still to come
    assert sorted(p.name for p in tmp_path.iterdir()) == [sequence.MARKER, *(p.name for p in paths)]
    with raybench.Renderer(scene, 160, 120, device="cpu", **options) as renderer:
        for path, cam in zip(paths, cameras, strict=True):
            np.testing.assert_array_equal(png(path), renderer.render(cam).image)
    running.client.wait_for_workers(2, timeout=60)  # the nanny restarted it, for the tests after this one
    assert victim not in running.client.run(os.getpid).values()


def test_a_sequence_whose_scene_is_lost_sends_its_frames_again(running, rng, tmp_path):
    """The scene's scattered copies lost mid-sequence (as when the workers
    holding them die): the scheduler forgets the tasks that needed them, and
    render_sequence scatters the scene again and sends those frames again,
    so none is missing and each is the frame render() makes."""
    scene, camera = scene_and_camera(rng, 30)
    cameras = camera_path.orbit(camera, 8)
    lost = []

    def on_frame(n, path):
        if not lost:
            futures = list(work._scattered.values())
            running.client.cancel(futures)  # every copy of the scene forgotten at once
            lost.append(len(futures))

    paths = cluster.render_sequence(
        running.client, scene, cameras, tmp_path, 48, 32, device="cpu",
        sequence_options=cluster.SequenceOptions(frames_per_task=1, on_frame=on_frame),
    )  # fmt: skip
    assert lost and lost[0] >= 1
    assert sorted(p.name for p in tmp_path.iterdir()) == [sequence.MARKER, *(p.name for p in paths)]
    with raybench.Renderer(scene, 48, 32, device="cpu") as renderer:
        for path, cam in zip(paths, cameras, strict=True):
            np.testing.assert_array_equal(png(path), renderer.render(cam).image)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_an_unreachable_scheduler_is_one_line_within_the_timeout(capsys):
    address = f"tcp://127.0.0.1:{free_port()}"
    start = time.perf_counter()
    with pytest.raises(RaybenchError, match=f"scheduler {address}: unreachable within 1 s"):
        cluster.Cluster(scheduler=address, timeout=1)
    assert time.perf_counter() - start < 5
    code = run(["render", "--spheres", "3", "--size", "16x8", "--scheduler", address, "--connect-timeout", "0.5"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"raybench: error: scheduler {address}: unreachable within 0.5 s")
    assert err.count("\n") == 1


def test_a_worker_without_the_device_is_named(running):
    with pytest.raises(RaybenchError, match=r"^worker tls://127\.0\.0\.1:\d+: .*no-such-adapter"):
        cluster.check_workers(running.client, "wgpu", adapter="no-such-adapter")


@pytest.fixture(scope="module")
def credentials(running, tmp_path_factory) -> dict[str, str]:
    """The running cluster's CA, certificate and key as PEM files, as a
    user of a tls:// scheduler holds them: by option name."""
    folder = tmp_path_factory.mktemp("tls")
    security = running.cluster.security
    files = {"--tls-ca": security.tls_ca_file, "--tls-cert": security.tls_client_cert,
             "--tls-key": security.tls_client_key}  # fmt: skip
    for name, pem in files.items():
        (folder / name[2:]).write_text(pem)
    return {name: str(folder / name[2:]) for name in files}


def tls_args(credentials) -> list[str]:
    return [arg for name, path in credentials.items() for arg in (name, path)]


@pytest.fixture
def dask_tls(credentials):
    """The credentials in Dask's own config, where a client finds them without options."""
    import dask

    config = {
        "distributed.comm.tls.ca-file": credentials["--tls-ca"],
        "distributed.comm.tls.client.cert": credentials["--tls-cert"],
        "distributed.comm.tls.client.key": credentials["--tls-key"],
    }
    with dask.config.set(config):
        yield


def test_a_tls_scheduler_without_credentials_is_one_line(running, capsys, monkeypatch):
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    address = running.client.scheduler.address
    assert run(["render", "--spheres", "3", "--size", "16x8", "--scheduler", address]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"raybench: error: scheduler {address}: a tls:// address needs this client's TLS ")
    assert "--tls-ca" in err and err.count("\n") == 1


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--tls-ca", "{ca}"], "--tls-ca: apply to --scheduler tls://... only"),
        (["--scheduler", "tcp://127.0.0.1:1", "--tls-ca", "{ca}"], "the scheduler's address must be tls://"),
        (["--scheduler", "tls://127.0.0.1:1", "--tls-ca", "{ca}"], "give --tls-ca and --tls-cert"),
        (
            ["--scheduler", "tls://127.0.0.1:1", "--tls-ca", "no-such-file", "--tls-cert", "{ca}"],
            "--tls-ca no-such-file: cannot be read (No such file or directory)",
        ),
    ],
)
def test_bad_tls_options_are_one_line(argv, message, credentials, capsys, monkeypatch):
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    argv = [a.format(ca=credentials["--tls-ca"]) for a in argv]
    assert run(["render", "--spheres", "3", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_a_scheduler_that_accepts_and_never_answers_is_one_line_within_the_timeout(capsys):
    """A tcp:// address where something accepts the connection and says
    nothing held render --scheduler past --connect-timeout, forever."""
    with socket.socket() as silent:
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)  # the kernel accepts; nothing ever answers
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
        start = time.perf_counter()
        with pytest.raises(RaybenchError, match=f"scheduler {address}: did not answer within 1 s"):
            cluster.Cluster(scheduler=address, timeout=1)
        assert time.perf_counter() - start < 30  # a hang guard, not a timing: the deadline is 1 s
        code = run(["render", "--spheres", "3", "--size", "16x8", "--scheduler", address, "--connect-timeout", "0.5"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"raybench: error: scheduler {address}: did not answer within 0.5 s")
    assert err.count("\n") == 1


SHORT_FRAMES = {
    # Dask's frames: 8 bytes of length, then a count of frames and their lengths; this says 5, holds none
    "a short frame": b"\x08" + b"\x00" * 7 + b"\x05" + b"\x00" * 7,
    "not msgpack": b"\x10" + b"\x00" * 7 + b"\x01" + b"\x00" * 7 + b"\x04" + b"\x00" * 7 + b"abcd",
}


@pytest.mark.parametrize("name", SHORT_FRAMES)
def test_a_peer_that_answers_nonsense_is_one_line(name, capsys):
    """A short Dask frame raised struct.error with a traceback (and bytes that
    are not msgpack, Dask's CRITICAL log with one): now one line, and no log."""
    import threading

    with socket.socket() as peer:
        peer.bind(("127.0.0.1", 0))
        peer.listen(8)
        address = f"tcp://127.0.0.1:{peer.getsockname()[1]}"

        def answer():
            with contextlib.suppress(OSError):
                while True:
                    conn, _ = peer.accept()
                    conn.sendall(SHORT_FRAMES[name])
                    conn.close()

        threading.Thread(target=answer, daemon=True).start()
        code = run(["render", "--spheres", "3", "--size", "16x8", "--scheduler", address, "--connect-timeout", "5"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith(f"raybench: error: scheduler {address}: "), err
    assert err.count("\n") == 1 and "Traceback" not in err, err


@pytest.mark.parametrize("fault", ["fifo", "folder", "not PEM", "key of another", "CA not PEM"])
def test_bad_tls_files_are_named_for_what_they_are(fault, credentials, tmp_path, capsys, monkeypatch):
    """A FIFO as --tls-ca hung in its open (waiting for a writer); a folder, a
    file that is not PEM or a key that is not the certificate's were told as
    'scheduler unreachable'. Each is now one line naming the option and what
    is wrong, before any connection."""
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    files = dict(credentials)
    bad = tmp_path / "bad.pem"
    if fault == "fifo":
        os.mkfifo(bad)
        files["--tls-ca"], expected = str(bad), f"--tls-ca {bad}: not a regular file"
    elif fault == "folder":
        bad.mkdir()
        files["--tls-cert"], expected = str(bad), "is a directory"  # click's own check, by name
    elif fault == "not PEM":
        bad.write_text("hello\n")
        files["--tls-cert"], expected = str(bad), "not a PEM certificate and its private key"
    elif fault == "CA not PEM":
        bad.write_text("-----BEGIN CERTIFICATE-----\nnot base64\n-----END CERTIFICATE-----\n")
        files["--tls-ca"], expected = str(bad), f"--tls-ca {bad}: not a PEM CA certificate"
    else:
        from distributed.security import Security

        (bad).write_text(Security.temporary().tls_client_key)
        files["--tls-key"], expected = str(bad), "not a PEM certificate and its private key"
    argv = ["render", "--spheres", "3", "--scheduler", "tls://127.0.0.1:1", *tls_args(files)]
    assert run(argv) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1 and "unreachable" not in err, err


def test_help_says_a_scheduler_is_trusted_with_code_execution(capsys):
    for command in ("render", "bench"):
        assert run([command, "--help"]) == 0
        text = " ".join(capsys.readouterr().out.split())
        assert "trusted with code execution" in text and "--tls-ca" in text and "tls://" in text


def test_cli_renders_tiles_and_a_sequence_on_a_running_cluster(running, rng, tmp_path, monkeypatch, capsys, dask_tls):
    monkeypatch.setenv("RAYBENCH_SCHEDULER", running.client.scheduler.address)
    seed = int(rng.integers(1000))
    out = tmp_path / "tiles.png"
    args = ["--spheres", "25", "--seed", str(seed), "--size", "56x40", "--device", "cpu"]
    assert run(["render", *args, "--tile", "16", "-o", str(out)]) == 0
    whole = raybench.render(raybench.random_spheres(25, seed), width=56, height=40, device="cpu")
    np.testing.assert_array_equal(png(out), whole.image)
    frames = tmp_path / "frames"
    gif = tmp_path / "orbit.gif"
    assert run(["render", *args, "--path", "orbit", "--frames", "3", "-o", str(frames), "--gif", str(gif)]) == 0
    assert sorted(p.name for p in frames.iterdir()) == [sequence.MARKER, *(f"frame_{n:05d}.png" for n in range(3))]
    out = capsys.readouterr().out
    assert "wrote 3 frames" in out and f"wrote {gif}: 3 frames" in out
    with Image.open(gif) as animated:
        # Pillow merges a frame the same as the one before into it (an orbit's frames that see no
        # sphere are the background alone), so the frames' times add up to 3 frames, not their count
        durations = []
        for n in range(animated.n_frames):
            animated.seek(n)
            durations.append(animated.info["duration"])
        assert animated.size == (56, 40) and sum(durations) == 3 * 1000 / raybench.gif.FPS


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--tile", "16"], "--tile applies across a cluster"),
        (["--frames", "3"], "--frames applies to --path only"),
        (["--path", "orbit"], "--path: give -o DIR"),
        (["--path", "orbit", "-o", "x.png"], "not a .png file"),
        (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not both"),
    ],
)
def test_cli_refuses_bad_cluster_options_in_one_line(argv, message, capsys, monkeypatch):
    monkeypatch.delenv("RAYBENCH_SCHEDULER", raising=False)
    assert run(["render", "--spheres", "3", *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


@contextlib.contextmanager
def interrupted_when(argv, ready):
    """argv run in a session of its own, sent SIGINT as a terminal sends
    Ctrl-C (to the whole process group, workers included) once ready(proc);
    yields (proc, its children then, its stderr) once it ended. Every wait is
    bounded; a child still there is killed before its pipe is read."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    with tempfile.TemporaryFile() as errors:
        proc = subprocess.Popen(
            argv, env=env, stdout=subprocess.DEVNULL, stderr=errors, start_new_session=True, preexec_fn=sigint_default
        )
        family = []
        try:
            deadline = time.monotonic() + 120
            while not (seen := ready(proc)) and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.1)
            with contextlib.suppress(psutil.NoSuchProcess):
                family = psutil.Process(proc.pid).children(recursive=True)
            os.killpg(proc.pid, signal.SIGINT)
            proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait(timeout=30)
        errors.seek(0)
        text = errors.read().decode()
    assert seen, f"not under way in time (exit {proc.returncode}): {text}"
    yield proc, family, text


@pytest.mark.slow
def test_ctrl_c_keeps_the_frames_written_and_stops_the_cluster(tmp_path):
    """Ctrl-C at a terminal: SIGINT to the whole process group, workers included."""
    out = tmp_path / "frames"
    argv = [sys.executable, "-m", "raybench", "render", "--spheres", "200", "--size", "160x120", "--device", "cpu",
            "--accel", "none", "--kernel", "simple", "--workers", "2", "--path", "orbit", "--frames", "2000",
            "-o", str(out)]  # fmt: skip
    with interrupted_when(argv, lambda proc: len(list(out.glob("frame_*.png"))) >= 3) as (proc, family, err):
        assert len(family) >= 2  # the workers
    # one line, no worker's traceback (the blank line before it is click's, after the terminal's ^C)
    assert proc.returncode == 130 and err.strip() == "raybench: interrupted", err
    _, alive = psutil.wait_procs(family, timeout=20)
    assert not alive, f"stray processes: {alive}"
    frames = sorted(out.glob("frame_*.png"))
    assert 3 <= len(frames) < 2000 and sorted(out.iterdir()) == [out / sequence.MARKER, *frames]
    cameras = camera_path.orbit(Camera(), 2000)
    scene = raybench.random_spheres(200, 0)
    with raybench.Renderer(scene, 160, 120, device="cpu", accel="none", kernel="simple") as renderer:
        for f in frames[:2] + frames[-1:]:  # the last one written whole too
            np.testing.assert_array_equal(png(f), renderer.render(cameras[int(f.stem[6:])]).image)


@pytest.mark.slow
def test_ctrl_c_during_a_frame_in_tiles_leaves_no_block_and_no_process(tmp_path):
    """Ctrl-C at a terminal while the workers write a frame's tiles into its shared block."""
    out = tmp_path / "frame.png"
    argv = [sys.executable, "-m", "raybench", "render", "--spheres", "4000", "--size", "1024x1024", "--device", "cpu",
            "--accel", "none", "--kernel", "simple", "--workers", "2", "-o", str(out)]  # fmt: skip

    def tiles_under_way(proc) -> bool:  # the frame's block is there, a second ago
        if any(name.startswith(f"{sharedframe.PREFIX}{proc.pid}-") for name in blocks()):
            time.sleep(1)
            return True
        return False

    with interrupted_when(argv, tiles_under_way) as (proc, family, err):
        named = f"{sharedframe.PREFIX}{proc.pid}-"
    assert proc.returncode == 130 and err.strip() == "raybench: interrupted", err
    _, alive = psutil.wait_procs(family, timeout=20)
    assert not alive, f"stray processes: {alive}"
    assert not any(name.startswith(named) for name in blocks()) and not out.exists()


def test_cuda_workers_are_pinned_one_gpu_each_within_those_visible(monkeypatch):
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    assert [s["options"]["env"]["CUDA_VISIBLE_DEVICES"] for s in cluster.worker_specs("cuda", 3).values()] == [
        "0", "1", "2"
    ]  # fmt: skip
    monkeypatch.setenv("CUDA_VISIBLE_DEVICES", "5, GPU-abc")
    specs = cluster.worker_specs("cuda", 2)
    assert [s["options"]["env"]["CUDA_VISIBLE_DEVICES"] for s in specs.values()] == ["5", "GPU-abc"]
    assert all(s["options"]["host"] == "127.0.0.1" and s["options"]["nthreads"] == 1 for s in specs.values())


@pytest.mark.slow
def test_a_frames_tiles_are_dealt_to_every_worker(running, rng, no_block_left):
    """As many tiles as workers: one on each, frame after frame (left to
    Dask, the two tiles of a frame went to one of two GPUs for a whole run)."""
    from distributed import get_task_stream

    scene, camera = scene_and_camera(rng, 200)
    workers = sorted(running.client.scheduler_info(n_workers=-1)["workers"])
    for _ in range(3):
        with get_task_stream(running.client) as stream:
            cluster.render(running.client, scene, camera, 64, 16 * len(workers), "cpu", rows=16)
        ran_on = sorted(t["worker"] for t in stream.data if "_tile" in str(t["key"]))
        assert ran_on == workers, ran_on


def test_a_worker_killed_mid_frame_loses_no_tile(running, rng, no_block_left):
    """A worker killed while it traces a tile: Dask traces that tile again elsewhere, and the frame is whole."""
    import threading

    scene, camera = scene_and_camera(rng, 400)
    options = {"accel": "none", "kernel": "simple"}  # tiles slow enough to be caught in the act
    done = {}
    job = threading.Thread(
        target=lambda: done.setdefault(
            "frame", cluster.render(running.client, scene, camera, 96, 240, "cpu", rows=8, **options)
        ),
        daemon=True,  # left behind, not awaited at exit, should it hang
    )
    pids = running.client.run(os.getpid)
    job.start()
    victim = None
    deadline = time.monotonic() + 60
    while victim is None and job.is_alive() and time.monotonic() < deadline:
        busy = running.client.processing()
        victim = next((w for w, keys in busy.items() if any("_tile" in str(k) for k in keys)), None)
    assert victim is not None, "no tile was seen in progress"
    os.kill(pids[victim], signal.SIGKILL)
    job.join(120)
    assert not job.is_alive()
    whole = raybench.render(scene, camera, 96, 240, device="cpu", **options)
    np.testing.assert_array_equal(done["frame"].image, whole.image)
    np.testing.assert_array_equal(done["frame"].hits, whole.hits)
    running.client.wait_for_workers(2, timeout=60)
    assert pids[victim] not in running.client.run(os.getpid).values()


# --- the benchmark on every machine -------------------------------------------------------

BENCH = ["bench", "--quick", "--suite", "thesis", "--device", "cpu", "--accel", "bvh", "--duration", "0.05"]


def bench_records(out):
    from raybench.bench import results

    (path,) = out.glob("results-*.jsonl")
    records = results.read(path)
    for i, record in enumerate(records):
        results.check_record(record, f"record {i}")
    return records


def test_cli_bench_runs_once_a_machine_on_a_worker(running, tmp_path, capsys, credentials):
    address = running.client.scheduler.address
    out = tmp_path / "out"
    assert run([*BENCH, "--scheduler", address, *tls_args(credentials), "--out", str(out)]) == 0
    assert "on 1 machine of" in capsys.readouterr().out  # both workers are on 127.0.0.1: one machine
    records = bench_records(out)
    workers = running.client.run(os.getpid)
    assert len(records) == 3  # 800x600 at 100, 500 and 1000 spheres, the BVH's
    (run_info,) = {json.dumps(r["run"], sort_keys=True) for r in records}
    settings = json.loads(run_info)["settings"]
    assert settings["worker"] in workers and settings["pid"] == workers[settings["worker"]] != os.getpid()
    assert settings["host"] == socket.gethostname() and settings["devices"] == ["cpu"]
    assert records[0]["run"]["label"] == machines._slug(socket.gethostname())
    assert [r["spheres"] for r in records] == [100, 500, 1000] and all(r["device"] == "cpu" for r in records)
    assert len(list(out.glob("report-*/report.md"))) == 1


@pytest.mark.slow
def test_cli_bench_puts_two_machines_side_by_side(running, tmp_path, monkeypatch, capsys, dask_tls):
    # one host here: each worker is made a machine of its own
    monkeypatch.setattr(machines, "machine_key", lambda worker: worker["id"])
    monkeypatch.setenv("RAYBENCH_SCHEDULER", running.client.scheduler.address)
    out = tmp_path / "out"
    assert run([*BENCH, "--label", "lab", "--out", str(out)]) == 0
    assert "on 2 machines of" in capsys.readouterr().out
    records = bench_records(out)
    host = machines._slug(socket.gethostname())
    labels = {f"lab-{host}", f"lab-{host}-2"}
    assert {r["run"]["label"] for r in records} == labels and len(records) == 6
    assert {r["run"]["settings"]["worker"] for r in records} == set(running.client.run(os.getpid))
    (report,) = out.glob("report-*/report.md")
    text = report.read_text()
    assert all(f"{label}, BVH" in text for label in labels)


def test_cli_bench_on_an_unreachable_scheduler_is_one_line(capsys):
    address = f"tcp://127.0.0.1:{free_port()}"
    start = time.perf_counter()
    assert run([*BENCH, "--scheduler", address, "--connect-timeout", "1"]) == 2
    assert time.perf_counter() - start < 5
    err = capsys.readouterr().err
    assert err.startswith(f"raybench: error: scheduler {address}: unreachable within 1 s") and err.count("\n") == 1


def test_cli_bench_names_the_worker_that_lacks_a_device(running, tmp_path, capsys, credentials):
    address = running.client.scheduler.address
    argv = ["bench", "--quick", "--device", "wgpu", "--adapter", "no-such-adapter", "--scheduler", address,
            *tls_args(credentials)]  # fmt: skip
    assert run([*argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert re.match(r"raybench: error: worker tls://127\.0\.0\.1:\d+: .*no-such-adapter", err) and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_cli_bench_ctrl_c_keeps_the_machines_records_written(running, tmp_path, monkeypatch, capsys, dask_tls):
    def one_machine_then_ctrl_c(client, settings, label, on_records):
        on_records([{"suite": "thesis", "n": 1}, {"suite": "thesis", "n": 2}])
        raise KeyboardInterrupt

    monkeypatch.setattr(machines, "bench", one_machine_then_ctrl_c)
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as stopped:
        run([*BENCH, "--scheduler", running.client.scheduler.address, "--out", str(out)])
    assert stopped.value.code == 130
    (path,) = out.glob("results-*.jsonl")
    assert [json.loads(line)["n"] for line in path.read_text().splitlines()] == [1, 2]
    assert "interrupted; the 2 finished points are in" in capsys.readouterr().err
