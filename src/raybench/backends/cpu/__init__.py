"""CPU backend: rows spread over threads, each running the compiled kernel
with the GIL released.

Brute force (accel "none") cuts the image into equal bands of rows, one per
thread: the thesis's own scheme ("divided up into eight threads, which each
process an equal amount of pixels"), any thread count from 1 to one per row.
Its two kernels: "simple", the thesis's loop a pixel at a time, and "fast",
which runs a SIMD cull test over groups of spheres before the exact test
(same pixels). With the BVH (accel "bvh", the default) the rays of a 16x8
tile of pixels walk the 4-wide tree together (kernels/packets.py), so each
node's boxes are tested against all of them with SIMD; with tree_width 2,
each ray walks the binary tree alone, by the GPUs' own walk
(kernels/traverse.py). A pixel's cost follows how many nodes
its ray crosses, which varies across the picture, so equal bands would
leave threads idle: the threads instead pull small chunks of rows from a
shared iterator until none are left.

Ctrl-C mid-frame: the bands run on the pool's threads (one thread's too),
while the main thread only waits, and so takes the signal at once; it then
sets the tracer's stop flag, which every kernel reads before each row (or
row of packets), and waits for the kernels to return: a frame of minutes
stops within a row's time, at no measured cost to a frame
(docs/notes/faults.md#ctrl-c-mid-frame).

fastmath stays off: the float32 arithmetic is then exactly IEEE, so the CPU image
is bit-identical to the CUDA kernel run under numba's simulator, and the tests
can hold the two to equality rather than to a tolerance.

The modules, by job: tracer (the Tracer: the pool of threads and the rows
they pull), program (kernels.make compiled for this backend: the pixel
programs and the binary tree's rows), brute (brute force's bands) and
whitted_rows (Whitted's rows). The walks themselves are in kernels/.
"""

from ...kernels.packets import PACKET, PACKET_H, PACKET_W
from ...kernels.shadow_packets import LANES
from .tracer import Tracer, bands, chunks, default_threads, description

__all__ = ["LANES", "PACKET", "PACKET_H", "PACKET_W", "Tracer", "bands", "chunks", "default_threads", "description"]
