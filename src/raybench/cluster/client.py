"""A Dask client and the cluster it talks to: an embedded one, started here,
or one joined by its scheduler's address.

- A worker owns one device: an embedded cluster starts one worker process
  per GPU, each pinned to its GPU by CUDA_VISIBLE_DEVICES, or with no GPU N
  processes that share the cores (each traces on cores // N threads). Every
  embedded process listens on 127.0.0.1 only, and only over TLS with a key
  made for this cluster and held in memory (Dask's Security.temporary()):
  whoever can reach a Dask port can run code there, so no other process,
  another user's least of all, gets in. A scheduler's address (scheduler=,
  or RAYBENCH_SCHEDULER) joins a cluster started elsewhere, trusted with
  code execution in this process (Dask sends pickles both ways); tls://
  addresses take the CA, certificate and key given, or Dask's config.

Why the embedded workers differ from Dask's defaults (docs/notes/scaling.md has
the measurements): a Nanny's worker gets MALLOC_TRIM_THRESHOLD_=65536 in its
environment, which makes glibc map and fault in afresh every frame-sized
allocation (several times slower copies of a frame); and a Nanny's default
thread count is every core, which runs several tasks at once on one device.
raybench's workers take one task at a time, without that variable.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import stat
import threading

from ..backends.limits import check_connect_timeout, check_worker_count
from ..errors import RaybenchError
from ..files import signals_held
from ..host import usable_cores
from .work import release

HOST = "127.0.0.1"  # every process of an embedded cluster listens here only
SCHEDULER_ENV = "RAYBENCH_SCHEDULER"
# How long to try a scheduler's address before saying it is unreachable.
CONNECT_TIMEOUT_S = 10.0
# An embedded worker silent this long (stopped, SIGSTOP, or hung) is let go, and its tasks go
# to the others or end in one line; Dask's default, 5 minutes, held a render past 8 minutes.
# A worker tracing or compiling still answers: its kernels release the GIL, and Numba's
# compiler lets the worker's event loop run between its steps.
WORKER_TTL_S = 60.0
# What an embedded cluster's Dask logs to the terminal (the nannies set it in this process too):
# critical failures only. What it logs as errors (a lost worker's scattered scene, the tasks
# forgotten with it; a restarted worker's warnings) raybench handles, or says in one line.
DASK_LOGS = logging.CRITICAL


def gpu_count() -> int:
    """NVIDIA GPUs this process can use (0 under numba's simulator)."""
    from .. import backends

    if not backends.cuda_available():
        return 0
    from numba import cuda

    return len(cuda.gpus)


def worker_specs(device: str, workers: int, security=None) -> dict:
    """The SpecCluster worker specs of an embedded cluster: `workers` Nanny
    processes on 127.0.0.1, one task at a time each; on cuda each pinned to
    one GPU, on the cpu each given its share of the cores. security (a
    distributed Security): their connections' (tls:// where it holds keys)."""
    from distributed import Nanny

    try:
        import psutil

        memory = psutil.virtual_memory().total // workers
    except ImportError:  # psutil is a dependency; without it Dask picks
        memory = "auto"
    specs = {}
    # the GPUs this process may use, in its own numbering: a worker pins one of them
    visible = [g.strip() for g in os.environ.get("CUDA_VISIBLE_DEVICES", "").split(",") if g.strip()]
    for i in range(workers):
        if device == "cuda":
            env = {"CUDA_VISIBLE_DEVICES": visible[i] if i < len(visible) else str(i)}
        else:
            env = {"NUMBA_NUM_THREADS": str(max(1, usable_cores() // workers))}
        for key in ("RAYBENCH_CACHE_DIR", "NUMBA_ENABLE_CUDASIM"):  # the compiled kernels' cache, and the simulator
            if key in os.environ:
                env[key] = os.environ[key]
        specs[f"{device}-{i}"] = {
            "cls": Nanny,
            "options": {
                "nthreads": 1,
                "host": HOST,
                "protocol": _protocol(security),
                "security": security,
                "dashboard_address": f"{HOST}:0",  # Dask's HTTP server (health, metrics) is always started
                "env": env,
                "preload": [__name__],  # dask_setup: Ctrl-C is the client's to handle
                "memory_limit": memory,
                "silence_logs": DASK_LOGS,
            },
        }
    return specs


def _protocol(security) -> str:
    return "tls" if security is not None and security.require_encryption else "tcp"


def embedded_security():
    """The credentials of a new embedded cluster: a self-signed key and
    certificate made now, in memory, that every process of the cluster and
    its client present to each other (mutual TLS): a process without them is
    refused. Dask passes them to the workers it starts through their
    nannies' pipes; they are on no disk but for the moment each process
    loads them (distributed.security, a private temporary folder)."""
    from distributed.security import Security

    return Security.temporary()


# Ctrl-C, and SIGTERM: blocked while an embedded cluster's workers are started (_ctrl_c_after).
_STOPS = {signal.SIGINT, signal.SIGTERM}
_MASKS = hasattr(signal, "pthread_sigmask")  # (not on Windows)


def dask_setup(worker) -> None:
    """Dask's hook as each embedded worker starts (worker_specs preloads this
    module there): Ctrl-C at a terminal reaches the whole process group, and
    each worker printed its own KeyboardInterrupt's tracebacks; the client
    handles it and ends the cluster, workers included, so they ignore it.
    The worker started with Ctrl-C and SIGTERM blocked (_ctrl_c_after): with
    its handler set, it takes them again; a Ctrl-C that came meanwhile is
    pending, and is ignored now."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if _MASKS:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOPS)


@contextlib.contextmanager
def _ctrl_c_after():
    """Ctrl-C and SIGTERM held while an embedded cluster starts, then raised,
    where the cluster is closed: raised inside Dask's start, Ctrl-C left a
    cluster half made for Dask's exit hook to fail on, with a traceback.
    Held twice over:
    - blocked in this thread (pthread_sigmask), and so in the threads Dask
      starts meanwhile and in the worker processes they spawn, which inherit
      the mask through fork and exec: a worker still importing took the
      terminal's Ctrl-C and printed its traceback, before any handler of its
      own was set. Each unblocks them once it is set (dask_setup). Here they
      wait, pending, and are delivered as the mask is put back: ignored
      meanwhile instead, the user's Ctrl-C would be lost;
    - caught by a Python handler (files' hold), for a signal that a thread
      started before, and not blocking it, takes for the process.
    multiprocessing starts its resource tracker with the first spawned
    process, blocking these signals for it and then unblocking them, ours
    with them: it is started first, here."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    if _MASKS:
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    with signals_held():
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _STOPS) if _MASKS else None
        try:
            yield
        finally:
            if _MASKS:
                signal.pthread_sigmask(signal.SIG_SETMASK, blocked)  # what came meanwhile is delivered here


def default_workers(device: str) -> int:
    return max(1, gpu_count()) if device == "cuda" else 1


class Cluster:
    """A Dask client and, unless it joined one by address, the embedded
    cluster it talks to; a `with` block closes both (the embedded workers'
    processes end with it).

        with raybench.cluster.Cluster(workers=2, device="cpu") as cluster:
            frame = raybench.cluster.render(cluster.client, scene, width=1680, height=1050, device="cpu")

    device picks the embedded workers' kind ("auto": one per GPU where
    there is one, else the CPU); scheduler (default: RAYBENCH_SCHEDULER)
    joins an existing cluster, tried for timeout seconds. security (a
    distributed.security.Security): an embedded cluster's connections, by
    default TLS with credentials made for it alone (embedded_security();
    Security() gives plain TCP, which any local process can join); a joined
    one's, by default Dask's config (distributed.comm.tls)."""

    def __init__(
        self,
        workers: int | None = None,
        device: str = "auto",
        scheduler: str | None = None,
        timeout: float = CONNECT_TIMEOUT_S,
        security=None,
    ):
        import dask
        from distributed import Client, Scheduler, SpecCluster

        from .. import backends

        scheduler = scheduler or os.environ.get(SCHEDULER_ENV) or None
        timeout = check_connect_timeout(timeout)
        self.cluster = None
        if scheduler is not None:
            if workers is not None:
                raise RaybenchError("workers: a joined cluster has its own; give workers or a scheduler, not both")
            self.client = connect(scheduler, timeout, security)
            return
        device = backends.resolve(device)
        if device == "wgpu":
            raise RaybenchError("device wgpu: the cluster runs cpu or cuda workers")
        if workers is None:
            workers = default_workers(device)
        workers = check_worker_count(workers)
        if device == "cuda" and not backends.module("cuda").simulated() and workers > gpu_count():
            raise RaybenchError(f"workers: {workers} cuda workers need {workers} GPUs; this machine has {gpu_count()}")
        # Dask's default sets MALLOC_TRIM_THRESHOLD_ in a worker's environment;
        # raybench's workers go without it (the module's docstring says why).
        environ = dict(dask.config.get("distributed.nanny.pre-spawn-environ"))
        environ.pop("MALLOC_TRIM_THRESHOLD_", None)
        if security is None:
            security = embedded_security()
        scheduler_options = {"host": HOST, "port": 0, "dashboard_address": f"{HOST}:0",
                             "protocol": _protocol(security), "security": security}  # fmt: skip
        try:
            ttl = f"{WORKER_TTL_S}s"
            config = {"distributed.nanny.pre-spawn-environ": environ, "distributed.scheduler.worker-ttl": ttl}
            with dask.config.set(config), _ctrl_c_after():
                self.cluster = SpecCluster(
                    scheduler={"cls": Scheduler, "options": scheduler_options},
                    workers=worker_specs(device, workers, security),
                    security=security,
                    silence_logs=DASK_LOGS,
                )
                self.client = Client(self.cluster)
        except BaseException:  # Ctrl-C held until now among them: nothing started is left running
            if getattr(self, "client", None) is not None:
                self.client.close()
            if self.cluster is not None:
                self.cluster.close()
            raise

    @property
    def workers(self) -> int:
        return len(self.client.scheduler_info(n_workers=-1)["workers"])

    def close(self) -> None:
        # an embedded cluster's workers end with it, their mappings too: asked only when joined
        release(self.client, workers=self.cluster is None)
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()
            self.cluster = None

    def __enter__(self) -> Cluster:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def connect(address: str, timeout: float = CONNECT_TIMEOUT_S, security=None):
    """A Client of the scheduler at address, or one line saying it was not
    reached within timeout seconds. security: a distributed Security (for
    tls:// addresses), by default Dask's config."""
    from distributed import Client
    from distributed.security import Security

    timeout = check_connect_timeout(timeout)
    if security is None:
        security = Security()  # Dask's config (distributed.comm.tls), as Client would read it
    if address.startswith("tls://") and not (security.tls_ca_file and security.tls_client_cert):
        raise RaybenchError(
            f"scheduler {address}: a tls:// address needs this client's TLS credentials: give --tls-ca, "
            "--tls-cert and --tls-key (Cluster(security=...)), or set Dask's distributed.comm.tls config"
        )
    if address.startswith("tls://"):
        check_tls(security.tls_ca_file, security.tls_client_cert, security.tls_client_key)
    _answers(address, timeout, security)
    try:
        return Client(address, timeout=timeout, security=security)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise RaybenchError(f"scheduler {address}: unreachable within {timeout:g} s ({reason})") from None


def _answers(address: str, timeout: float, security) -> None:
    """One line unless a Dask scheduler at address answers within timeout
    seconds: Client's own wait had no deadline once a connection was
    accepted, and a process that accepted and never answered held it forever."""
    import asyncio

    from distributed.comm import connect as comm_connect

    async def identity():
        comm = await comm_connect(address, timeout=timeout, **security.get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            await comm.read()
        finally:
            comm.abort()

    # What the peer sends is Dask's to decode, which logs its failures (a traceback) before raising them.
    protocol = logging.getLogger("distributed.protocol")
    level, protocol.level = protocol.level, logging.CRITICAL + 1
    try:
        asyncio.run(asyncio.wait_for(identity(), timeout))
    except TimeoutError:
        if not _accepts(address):  # refused all along: Dask's connect retries until the deadline
            raise RaybenchError(f"scheduler {address}: unreachable within {timeout:g} s") from None
        raise RaybenchError(
            f"scheduler {address}: did not answer within {timeout:g} s (something accepted the connection, "
            "but no Dask scheduler answered it)"
        ) from None
    except (OSError, EOFError) as exc:  # refused, a name not found, closed, TLS refused
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise RaybenchError(f"scheduler {address}: unreachable within {timeout:g} s ({reason})") from None
    except Exception as exc:  # noqa: BLE001 -- a peer's bytes, any decoding error of Dask's (struct.error, msgpack's)
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise RaybenchError(f"scheduler {address}: answered, but not as a Dask scheduler does ({reason})") from None
    finally:
        protocol.level = level


def _accepts(address: str) -> bool:
    """Whether something accepts a TCP connection at address (tcp:// or tls://), within a second."""
    import socket

    from distributed.comm import parse_address, parse_host_port

    try:
        host, port = parse_host_port(parse_address(address)[1])
        with socket.create_connection((host, port), timeout=1.0):
            return True
    except (OSError, ValueError, TypeError):
        return False


# Where Dask's Security takes the credentials themselves rather than their files.
_PEM = "-----BEGIN"


def check_tls(ca, cert, key=None, names=("tls_ca_file", "tls_client_cert", "tls_client_key")) -> None:
    """The TLS credentials' files named for what is wrong with them, before
    any connection: missing, not a regular file (opening a FIFO waits for a
    writer, forever), unreadable, or not a PEM CA, certificate or key. They
    were all told as "scheduler unreachable". names: the options' (the CLI's
    --tls-ca, --tls-cert, --tls-key) or Security's attributes."""
    import ssl

    files = [(name, path) for name, path in zip(names, (ca, cert, key)) if path and not str(path).startswith(_PEM)]
    for name, path in files:
        try:
            info = os.stat(path)
        except OSError as exc:
            raise RaybenchError(f"{name} {path}: cannot be read ({exc.strerror or exc})") from None
        if not stat.S_ISREG(info.st_mode):
            raise RaybenchError(f"{name} {path}: not a regular file (a FIFO, a device or a folder); give a PEM file")
        try:
            with open(path, "rb") as f:
                f.read(1)
        except OSError as exc:
            raise RaybenchError(f"{name} {path}: cannot be read ({exc.strerror or exc})") from None
    if len(files) < 2 + bool(key) or any(str(p).startswith(_PEM) for p in (ca, cert, key) if p):
        return  # credentials given inline: Dask reads them
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    try:
        context.load_verify_locations(cafile=ca)
    except (ssl.SSLError, ValueError) as exc:
        raise RaybenchError(f"{names[0]} {ca}: not a PEM CA certificate ({exc.reason or exc})") from None
    try:
        context.load_cert_chain(cert, key)
    except (ssl.SSLError, ValueError) as exc:
        which = f"{names[1]} {cert}" + (f" and {names[2]} {key}" if key else "")
        raise RaybenchError(f"{which}: not a PEM certificate and its private key ({exc.reason or exc})") from None
