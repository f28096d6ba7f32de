"""raybench.cluster when every worker dies at once: here the only one of an
embedded cluster (as in every plain `--path` run), killed mid-job. Its nanny
restarts it, the client waits for it, sends the scene again and the lost
tasks again, and the result is the one a single process makes; where no
worker comes back, one line says so (RaybenchError) instead of Dask's
FutureCancelledError.

Every wait here is bounded: the job runs on a daemon thread joined with a
timeout, and the killer polls with a deadline."""

import contextlib
import os
import signal
import threading
import time

import numpy as np
import pytest
from PIL import Image

import raybench
from raybench import Camera, RaybenchError, camera_path, cluster, sequence
from raybench.cluster import work

pytest.importorskip("distributed")

JOB_S = 180  # a job that outlives this failed (or hung): the thread is a daemon, left behind
OPTIONS = {"accel": "none", "kernel": "simple"}  # tasks slow enough to be caught in the act


@pytest.fixture(scope="module")
def lone():
    raybench.render(raybench.random_spheres(3), width=16, height=8, device="cpu", **OPTIONS)  # compiled here first
    with cluster.Cluster(workers=1, device="cpu") as c:
        c.client.wait_for_workers(1, timeout=120)
        yield c


def worker_pid(client) -> int:
    (pid,) = client.run(os.getpid).values()
    return pid


def in_background(job) -> dict:
    """job() on a daemon thread: {"thread", and "result" or "error" once it ends}."""
    out: dict = {}

    def run():
        try:
            out["result"] = job()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            out["error"] = exc

    out["thread"] = threading.Thread(target=run, daemon=True)
    out["thread"].start()
    return out


def kill_when_busy(client, pid: int, prefix: str, job: dict) -> None:
    """SIGKILL to the worker once a task named prefix... is in progress on it."""
    deadline = time.monotonic() + 60
    while job["thread"].is_alive() and time.monotonic() < deadline:
        if any(prefix in str(key) for keys in client.processing().values() for key in keys):
            os.kill(pid, signal.SIGKILL)
            return
        time.sleep(0.02)
    raise AssertionError(f"no {prefix} task was seen in progress")


def finished(job: dict):
    job["thread"].join(JOB_S)
    assert not job["thread"].is_alive(), "the job did not end after its worker was killed"
    if "error" in job:
        raise job["error"]
    return job["result"]


def test_the_only_worker_killed_mid_frame_is_restarted_and_the_frame_is_whole(lone, rng):
    scene = raybench.random_spheres(400, seed=int(rng.integers(2**31)))
    camera = Camera(position=tuple(rng.uniform(-0.3, 0.3, 3)))
    pid = worker_pid(lone.client)
    job = in_background(lambda: cluster.render(lone.client, scene, camera, 96, 480, "cpu", rows=8, **OPTIONS))
    kill_when_busy(lone.client, pid, "_tile", job)
    frame = finished(job)
    whole = raybench.render(scene, camera, 96, 480, device="cpu", **OPTIONS)
    np.testing.assert_array_equal(frame.image, whole.image)
    np.testing.assert_array_equal(frame.hits, whole.hits)
    lone.client.wait_for_workers(1, timeout=60)
    assert worker_pid(lone.client) != pid  # restarted: the frame was traced by the new one


@pytest.mark.slow
def test_the_only_worker_killed_mid_sequence_loses_no_frame(lone, rng, tmp_path):
    scene = raybench.random_spheres(200, seed=int(rng.integers(2**31)))
    cameras = camera_path.orbit(Camera(), 12)
    pid = worker_pid(lone.client)
    job = in_background(
        lambda: cluster.render_sequence(
            lone.client,
            scene,
            cameras,
            tmp_path,
            96,
            72,
            device="cpu",
            sequence_options=cluster.SequenceOptions(frames_per_task=1),
            **OPTIONS,
        )  # fmt: skip
    )
    kill_when_busy(lone.client, pid, "_frames", job)
    paths = finished(job)
    assert sorted(p.name for p in tmp_path.iterdir()) == [sequence.MARKER, *(p.name for p in paths)]
    with raybench.Renderer(scene, 96, 72, device="cpu", **OPTIONS) as renderer:
        for path, camera in zip(paths, cameras, strict=True):
            np.testing.assert_array_equal(np.asarray(Image.open(path).convert("RGB")), renderer.render(camera).image)
    lone.client.wait_for_workers(1, timeout=60)
    assert worker_pid(lone.client) != pid


@pytest.mark.slow
def test_workers_that_do_not_come_back_are_one_line(monkeypatch):
    """A nanny that cannot restart its worker: the client waits
    RESTART_WAIT_S for one, then says in one line what was lost."""
    monkeypatch.setattr(work, "RESTART_WAIT_S", 2.0)
    with cluster.Cluster(workers=1, device="cpu") as c:
        c.client.wait_for_workers(1, timeout=120)
        (nanny,) = c.cluster.workers.values()

        async def not_restarted():
            raise RuntimeError("the test's nanny restarts no worker")

        nanny.instantiate = not_restarted  # what the nanny calls to restart its worker (distributed 2026.8)
        pid = worker_pid(c.client)
        scene = raybench.random_spheres(400, seed=5)
        job = in_background(lambda: cluster.render(c.client, scene, None, 96, 480, "cpu", rows=8, **OPTIONS))
        kill_when_busy(c.client, pid, "_tile", job)
        with pytest.raises(RaybenchError) as info:
            finished(job)
    message = str(info.value)
    assert message.startswith("cluster: its workers were lost, with rows ") and "none was back within 2 s" in message
    assert "\n" not in message


def test_the_only_worker_killed_mid_measurement_is_one_line(lone, rng):
    """trace_frames (the multi-gpu suite's throughput) does not send lost
    frames again, which would time the restart too: one line says so."""
    scene = raybench.random_spheres(200, seed=int(rng.integers(2**31)))
    cameras = camera_path.orbit(Camera(), 12)
    lone.client.wait_for_workers(1, timeout=60)
    pid = worker_pid(lone.client)
    job = in_background(
        lambda: cluster.trace_frames(lone.client, scene, cameras, 96, 72, "cpu", frames_per_task=1, **OPTIONS)
    )
    kill_when_busy(lone.client, pid, "_hit_counts", job)
    with pytest.raises(RaybenchError, match="^cluster: frames were lost with their workers mid-measurement"):
        finished(job)
    lone.client.wait_for_workers(1, timeout=60)


def test_a_stopped_worker_ends_the_render_in_time(monkeypatch, rng):
    """A worker stopped with SIGSTOP (its connections open, silent) held a
    render forever (past 8 minutes under Dask's 5-minute worker TTL): an
    embedded cluster lets a worker go once silent for WORKER_TTL_S (3 s here),
    and the frame then ends, whole or in one line."""
    from raybench.cluster import client as cluster_client

    monkeypatch.setattr(cluster_client, "WORKER_TTL_S", 3.0)
    scene = raybench.random_spheres(400, seed=int(rng.integers(2**31)))
    with cluster.Cluster(workers=1, device="cpu") as c:
        c.client.wait_for_workers(1, timeout=120)
        pid = worker_pid(c.client)
        try:
            job = in_background(lambda: cluster.render(c.client, scene, width=320, height=240, device="cpu", **OPTIONS))
            deadline = time.monotonic() + 60
            while job["thread"].is_alive() and time.monotonic() < deadline:
                if any("_tile" in str(key) for keys in c.client.processing().values() for key in keys):
                    break
                time.sleep(0.02)
            os.kill(pid, signal.SIGSTOP)
            job["thread"].join(JOB_S)
            assert not job["thread"].is_alive(), "the render did not end after its only worker was stopped"
            if "error" in job:
                assert isinstance(job["error"], RaybenchError) and "\n" not in str(job["error"]), job["error"]
            else:
                assert job["result"].image.shape == (240, 320, 3)
        finally:
            with contextlib.suppress(ProcessLookupError):  # its nanny may have restarted it already
                os.kill(pid, signal.SIGKILL)  # (a stopped process takes SIGKILL): the cluster closes at once
