import gc
import os
import shutil
import signal
import time

import numpy as np
import pytest

# Without a GPU, the CUDA kernel runs under numba's simulator; with one (the GPU
# machine), the same tests run it for real. This must be decided before numba.cuda
# is first imported.
if "NUMBA_ENABLE_CUDASIM" not in os.environ:
    os.environ["NUMBA_ENABLE_CUDASIM"] = "0" if shutil.which("nvidia-smi") else "1"


def _simulated_threads_yield() -> None:
    """The simulator runs a block as a Python thread per CUDA thread, and its
    BlockManager.run polls them (t.is_alive() for each, in a loop without a
    wait: numba-cuda 0.30.4) until all end. That loop holds the GIL for
    whole switch intervals, so the fewer threads are still running, the
    larger its share of the time: cuda's wavefront cases took several times
    as long as with the poll handing the GIL on (the README's test command). The poll now yields (sleep(0)
    releases the GIL) once for as many threads as the block has, about once
    a pass (a yield every poll was slower: a switch of thread each); what the
    threads compute, and when they meet at syncthreads, is unchanged."""
    from numba.cuda.simulator import kernel

    alive = kernel.BlockThread.is_alive

    def is_alive(thread) -> bool:
        manager = thread._manager
        manager.polls = getattr(manager, "polls", 0) + 1
        if manager.polls % manager.block_state.size == 0:  # about once a pass over the block's threads
            time.sleep(0)
        return alive(thread)

    kernel.BlockThread.is_alive = is_alive


if os.environ["NUMBA_ENABLE_CUDASIM"] == "1":
    _simulated_threads_yield()


def sigint_default() -> None:
    """Popen's preexec_fn for a child that a test sends SIGINT: its default
    action. A shell that starts the tests in the background (or nohup, or a
    script's `&`) starts them with SIGINT ignored, which every child inherits
    through exec, and Python then never raises KeyboardInterrupt in it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def sigint_handled():
    """Python's own SIGINT handler (KeyboardInterrupt) in this process for one
    test, whatever the run inherited (sigint_default says why it may be
    ignored); what was there before is put back after."""
    before = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@pytest.fixture
def rng(request):
    """A fresh random generator per test; its seed is printed when the test
    fails, and RAYBENCH_TEST_SEED=that seed gives the same inputs again."""
    given = os.environ.get("RAYBENCH_TEST_SEED")
    seed = int(given) if given else int(np.random.SeedSequence().entropy % 2**63)
    request.node.user_properties.append(("seed", seed))
    print(f"random seed: {seed} (RAYBENCH_TEST_SEED={seed} repeats it)")
    return np.random.default_rng(seed)


@pytest.fixture(scope="session")
def adapter() -> str:
    """The name of the wgpu adapter to trace on: the best one found, named, so
    that a CPU driver (lavapipe) is used too. Where there is none the test
    skips, or fails under RAYBENCH_REQUIRE_WGPU=1 (CI)."""
    from raybench.backends.wgpu import adapters

    found = adapters.found()
    if not found:
        reason = "wgpu finds no adapter (on Debian: apt-get install mesa-vulkan-drivers libvulkan1)"
        if os.environ.get("RAYBENCH_REQUIRE_WGPU") == "1":
            pytest.fail(f"{reason}; RAYBENCH_REQUIRE_WGPU=1 requires the wgpu tests to run")
        pytest.skip(reason)
    return found[0].name


def pytest_sessionfinish(session, exitstatus):
    """GPU objects that tests left in reference cycles (closed windows' wgpu
    devices) are released now, with the interpreter whole, rather than during
    its shutdown, when wgpu stops a device's polling thread without waiting
    for it."""
    gc.collect()
