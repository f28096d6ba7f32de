"""The multi-gpu suite's measurement: the throughput of N workers of an
embedded raybench.cluster on one job, "frame" (one large frame in tiles,
assembled here: cluster.render) or "sequence" (an orbit's frames traced on
the workers: cluster.trace_frames).

A point's cluster is started once for the points of the same device and
worker count (they are consecutive in suites.points), and warmed by one
untimed run: every worker has then loaded its kernels and built its tree,
which is start-up, not throughput. Then the job runs for the point's
duration (at least MIN_RUNS times); each run's frames / seconds is a sample.
"""

from __future__ import annotations

import time

from .. import camera_path, cluster
from ..camera import Camera
from .stats import kept_samples, summarize
from .suites import Point

MIN_RUNS = 3
# The orbit's camera: outside the random spheres' cloud (random_spheres puts
# them in front of the default camera, towards +z), circling its middle.
ORBIT_CAMERA = Camera(position=(0.0, 0.0, -1.0), look_at=(0.0, 0.0, 2.0))


class Clusters:
    """The one cluster open at a time, reused while the points ask for the same."""

    def __init__(self):
        self.key, self.cluster = None, None

    def get(self, device: str, workers: int) -> cluster.Cluster:
        if self.key != (device, workers):
            self.close()
            self.cluster = cluster.Cluster(workers=workers, device=device)
            self.cluster.client.wait_for_workers(workers)
            self.key = (device, workers)
        return self.cluster

    def close(self) -> None:
        if self.cluster is not None:
            self.cluster.close()
        self.key, self.cluster = None, None


def options(point: Point) -> dict:
    """The device options of a point (workers, job and frames are the suite's)."""
    return {k: v for k, v in point.options.items() if k in ("accel", "threads")}


def measure(point: Point, scenes, duration: float, clusters: Clusters) -> dict:
    workers = point.options["workers"]
    client = clusters.get(point.device, workers).client
    scene = scenes.get(point.spheres)
    if point.options["job"] == "frame":
        frames = 1

        def run():
            cluster.render(client, scene, None, point.width, point.height, point.device, **options(point))
    else:
        cameras = camera_path.orbit(ORBIT_CAMERA, point.options["frames"])
        frames = len(cameras)

        def run():
            cluster.trace_frames(client, scene, cameras, point.width, point.height, point.device, **options(point))

    start = time.perf_counter()
    run()  # warm: compiled or loaded, tree built, buffers made on every worker that took a task
    first_s = time.perf_counter() - start
    samples = []
    end = time.perf_counter() + duration
    while time.perf_counter() < end or len(samples) < MIN_RUNS:
        start = time.perf_counter()
        run()
        samples.append((time.perf_counter() - start) * 1e3 / frames)  # ms a frame
    frame_ms = summarize(samples)
    return {
        "suite": point.suite,
        "test": None,
        "device": point.device,
        "width": point.width,
        "height": point.height,
        "spheres": point.spheres,
        "options": point.options,
        "frames": frames * len(samples),
        "frame_ms": frame_ms,
        "samples_ms": kept_samples(samples),
        "kernel_ms": None,
        "first_frame_s": first_s,
        "compile_s": None,
        "build_s": None,
        "rays_per_s": point.width * point.height / (frame_ms["median"] / 1e3),
        "tests_per_s": None,
        "frames_per_s": 1e3 / frame_ms["median"],
    }
