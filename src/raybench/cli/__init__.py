"""The command line: raybench render | view | info | bench | warmup | report | compare | schema | scene.

One module a command (render.py, view.py, ...), the options they share
written once (options.py); this module gathers them under one group, and
run() turns every mistake a user can make into one line on stderr and exit
code 2: no traceback reaches the terminal for input we can name.
"""

from __future__ import annotations

import sys

import click

from .. import __version__
from ..errors import RaybenchError, Terminated, device_failure, one_line
from . import bench, compare, info, render, report, scene, schema, view, warmup
from .options import device_options, parse_pair, parse_size

__all__ = ["device_options", "entry", "main", "parse_pair", "parse_size", "run"]


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(version=__version__, prog_name="raybench")
def main():
    """raybench: the thesis's ray tracer on CPU and GPU, and what the GPU buys."""


for _command in (
    render.render,
    view.view,
    info.info,
    bench.bench,
    warmup.warmup,
    report.report_cmd,
    compare.compare_cmd,
    schema.schema_cmd,
    scene.scene_cmd,
):
    main.add_command(_command)


def _interrupted(what: str = "interrupted", code: int = 130) -> int:
    """Ctrl-C (or SIGTERM, Terminated): one line, exit 130 (143), and a child
    compiling the builder for later runs (bvh.one_shot) stopped rather than awaited."""
    oneshot = sys.modules.get("raybench.bvh.oneshot")  # not imported: no child was started
    if oneshot is not None:
        oneshot.stop_compiling_elsewhere()
    click.echo(f"raybench: {what}", err=True)
    return code


def _terminate(signum, frame):
    raise Terminated


OUT_OF_MEMORY = (
    "out of memory (a ulimit or container limit may be lower than the free memory); "
    "use a smaller --size or fewer --spheres"
)


def _no_thread(exc: BaseException) -> bool:
    """Python's error where the system refuses a new thread (EAGAIN: its
    stack's address space under ulimit -v, or ulimit -u's processes)."""
    return type(exc) is RuntimeError and str(exc) == "can't start new thread"


def run(argv=None) -> int:
    """Entry point: turn every user error into one line and exit code 2."""
    try:
        # a command's ctx.exit(code) comes back as its return value (compare --fail-slower's 1)
        code = main.main(args=argv, prog_name="raybench", standalone_mode=False)
    except RaybenchError as exc:
        click.echo(f"raybench: error: {one_line(exc)}", err=True)
        return 2
    except click.exceptions.NoArgsIsHelpError as exc:
        click.echo(exc.ctx.get_help() if exc.ctx else str(exc))
        return 2
    except click.UsageError as exc:
        hint = (
            f" (see 'raybench {exc.ctx.command_path.split(' ', 1)[1]} --help')"
            if exc.ctx and " " in exc.ctx.command_path
            else " (see 'raybench --help')"
        )
        click.echo(f"raybench: error: {one_line(exc.format_message())}{hint}", err=True)
        return 2
    except click.ClickException as exc:
        click.echo(f"raybench: error: {one_line(exc.format_message())}", err=True)
        return exc.exit_code
    except (click.exceptions.Abort, KeyboardInterrupt) as exc:
        # click turns a KeyboardInterrupt inside a command into Abort, raised from it
        if isinstance(exc, Terminated) or isinstance(exc.__cause__, Terminated):
            return _interrupted("terminated (SIGTERM)", 143)
        return _interrupted()
    except MemoryError:
        # Checked before the large allocations (limits.host_available_bytes);
        # this is for the rest, under a ulimit or cgroup limit we could not foresee.
        click.echo(f"raybench: error: {OUT_OF_MEMORY}", err=True)
        return 2
    except Exception as exc:
        if _no_thread(exc):
            # The same, for the threads: their stacks are counted in the check
            # (host_available_bytes), but a library may start threads of its own.
            click.echo(f"raybench: error: cannot start a thread: {OUT_OF_MEMORY}; or fewer --threads", err=True)
            return 2
        failure = device_failure(exc)
        if failure is None:
            raise
        click.echo(f"raybench: error: {one_line(failure)}; the run was stopped", err=True)
        return 2
    return code if isinstance(code, int) else 0


def entry() -> None:
    import signal

    # SIGTERM ends the process as Ctrl-C does, its cleanups run (errors.Terminated);
    # its default action left a report's half-made folder and leaked semaphores.
    signal.signal(signal.SIGTERM, _terminate)
    try:
        code = run()
        if code in (130, 143):
            _ignore_ctrl_c()
        # A one-shot picture may have started a child that compiles the builder
        # for later runs (bvh.one_shot): it is awaited here, where Ctrl-C is caught,
        # rather than during the interpreter's shutdown, where it would print a traceback.
        oneshot = sys.modules.get("raybench.bvh.oneshot")  # not imported: no child was started
        if oneshot is not None:
            oneshot.wait_for_compiling_elsewhere()  # Ctrl-C meanwhile stops the child, quietly
    except KeyboardInterrupt as exc:  # Ctrl-C (or SIGTERM) between run's own handlers and the wait
        code = _interrupted("terminated (SIGTERM)", 143) if isinstance(exc, Terminated) else _interrupted()
        _ignore_ctrl_c()
    sys.exit(code)


def _ignore_ctrl_c() -> None:
    """Ctrl-C was handled and said so: the process only ends now. Pressed
    again meanwhile, it would print a second line or a traceback, or, during
    Python's own shutdown, kill the process by the signal (no exit code 130)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
