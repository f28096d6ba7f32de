"""A kernel launch with its arguments converted once, for launches repeated
with the same arguments.

numba-cuda converts every argument of every launch in Python, some
microseconds a device array, so a kernel of many arrays costs far more to
launch than with its arguments converted beforehand (`benchmarks/archive/launch_overhead.py`
measures it; docs/notes/startup.md#a-launchs-arguments-converted-once).
The GPU builder launches 20 kernels a build, each on the same arrays build
after build, so below a few hundred thousand spheres the host's conversions
were most of a build
(docs/notes/gpu-build.md#the-trees-quality-raised-on-the-gpu-sah-leaves-and-treelets).

`Launches` keeps the prepared launches of a Tracer or a Builder by their
arguments, so each is converted once; its owner clears it when it replaces
an array the launches were prepared with (a rebuilt tree), which would
otherwise stay alive in them.

`Prepared(kernel, grid, block, *args)` launches once through numba-cuda
(which compiles and checks the arguments), then keeps the converted
arguments and launches again through cuda.core, as numba-cuda itself does
after converting them. It holds the arguments, so the device pointers it
converted stay valid. Under numba's simulator, or where a launch needs
numba-cuda each time (host arrays copied over, a debug kernel), it launches
through numba-cuda every time: the same kernel, the same arguments.
"""

from __future__ import annotations

from collections import OrderedDict

import numba
import numpy as np

_SCALARS = (int, float, np.generic)


class Launches:
    """The last `size` launches, prepared, by kernel, grid, block and
    arguments (arrays by identity: a kept launch holds its arrays, so an id
    cannot be another array's while it is kept)."""

    def __init__(self, size: int = 4):
        self._kept: OrderedDict = OrderedDict()
        self._size = size

    def __call__(self, kernel, grid, block, *args) -> None:
        key = (id(kernel), grid, block, *((type(a), a) if isinstance(a, _SCALARS) else id(a) for a in args))
        step = self._kept.get(key)
        if step is None:
            self._kept[key] = Prepared(kernel, grid, block, *args)
            if len(self._kept) > self._size:
                self._kept.popitem(last=False)
        else:
            self._kept.move_to_end(key)
            step()

    def clear(self) -> None:
        self._kept.clear()


class Prepared:
    """One launch, made now through numba-cuda and kept ready to be made
    again with the same arguments: call it."""

    def __init__(self, kernel, grid, block, *args):
        self._kernel, self._grid, self._block, self._args = kernel, grid, block, args
        kernel[grid, block](*args)
        self._fast = _converted(kernel, grid, block, args)

    @property
    def converted(self) -> bool:
        """Whether later launches skip numba-cuda's conversions."""
        return self._fast is not None

    def __call__(self) -> None:
        if self._fast is None:
            self._kernel[self._grid, self._block](*self._args)
        else:
            launch, launch_args = self._fast
            launch(*launch_args)


# numba-cuda's own conversion of a launch's arguments (`_Kernel._prepare_args`,
# numba-cuda 0.30, whose version pyproject.toml pins), read here and nowhere
# else: the three functions below are what Prepared and
# benchmarks/archive/launch_overhead.py take apart.


def core_stream():
    """numba-cuda's default stream, as it hands it to cuda.core."""
    from numba.cuda.cudadrv import driver

    return driver._to_core_stream(0)


def convert_args(compiled, args, stream) -> tuple[list, list]:
    """The compiled kernel's (an entry of kernel.overloads) arguments converted as numba-cuda
    converts them for a launch on stream: (the launch's arguments, what it copies back)."""
    kernelargs, writeback = [], []
    for ty, value in zip(compiled.argument_types, args):
        compiled._prepare_args(ty, value, stream, writeback, kernelargs)
    return kernelargs, writeback


def kernel_handle(compiled):
    """The compiled kernel's cuda.core kernel, which cuda.core's launch takes."""
    return compiled._codelibrary.get_cufunc().kernel


def _converted(kernel, grid, block, args):
    """(cuda.core's launch, its arguments) for this launch, or None where the
    kernel must go through numba-cuda each time."""
    if numba.config.ENABLE_CUDASIM:
        return None
    try:
        from cuda.core import LaunchConfig, launch
    except ImportError:
        return None
    overloads = list(kernel.overloads.values())
    if len(overloads) == 1:
        compiled = overloads[0]
    else:
        compiled = kernel.overloads.get(tuple(kernel.typeof_pyval(a) for a in args))
    if compiled is None or compiled.debug or compiled.cooperative:
        return None
    stream = core_stream()
    kernelargs, writeback = convert_args(compiled, args, stream)
    if writeback:  # a host array, copied to the device by each launch and back
        return None
    return launch, (stream, LaunchConfig(grid=grid, block=block), kernel_handle(compiled), *kernelargs)
