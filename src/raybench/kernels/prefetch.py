"""A hint to the processor to bring an array element's cache line in before
it is read (LLVM's llvm.prefetch).

Why: a packet of primary rays through a dense mesh spends much of its frame
waiting for loads, a triangle's nine values and a node's two lines, that
nothing asked for before the walk reached them. The closest-hit packet walk
(kernels/packets.py) asks for what a child it has entered will read as it
pushes the child: an inner child's node, a leaf's first lines where the
kind's leaf values lie together (CPU_LEAF_ORDER "F"). The loads are then
under way while the node's other boxes are tested and the nearer children
walked. The figures: docs/notes/embree.md#the-walks-reads-asked-for-ahead-2026-12-05.

Written inline in the walk: the same hints in a function of this module,
inlined by Numba, made the frames slower than none.
"""

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def prefetch(typingctx, array, i, j):
    """Prefetch array[i, j] (a 2-D array) for a read, to be kept in every
    cache level. No bounds check: a prefetch reads nothing and never
    faults, so a line past the array's end is only a wasted hint. `array`
    may be a mesh's leaves read through the tree's order (kernels/tree_leaves.py):
    then column i of the face of its j-th triangle, whose order entry is read."""
    sig = types.void(array, i, j)

    def codegen(context, builder, sig, args):
        array_type = sig.args[0]
        index = [context.cast(builder, a, t, types.intp) for a, t in zip(args[1:], sig.args[1:])]
        if isinstance(array_type, types.BaseTuple):
            # a mesh's leaves read through the tree's order, (vertices, faces, order): the face of
            # the tree's j-th triangle, whose order entry is read for it
            faces_type, order_type = array_type[1], array_type[2]
            faces = context.make_array(faces_type)(context, builder, builder.extract_value(args[0], 1))
            order = context.make_array(order_type)(context, builder, builder.extract_value(args[0], 2))
            # a real read, so kept within the order (j past a leaf's end falls on the last entry)
            last = builder.sub(cgutils.unpack_tuple(builder, order.shape, 1)[0], ir.Constant(index[1].type, 1))
            j = builder.select(builder.icmp_signed("<", index[1], last), index[1], last)
            at = cgutils.get_item_pointer(context, builder, order_type, order, [j], wraparound=False)
            k = context.cast(builder, builder.load(at), order_type.dtype, types.intp)
            array_type, made, index = faces_type, faces, [k, index[0]]
        else:
            made = context.make_array(array_type)(context, builder, args[0])
        pointer = cgutils.get_item_pointer(context, builder, array_type, made, index, wraparound=False)
        byte_pointer = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        function = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [byte_pointer, i32, i32, i32]), "llvm.prefetch.p0"
        )
        # (address, 0: a read, 3: keep in every level, 1: data)
        builder.call(function, [builder.bitcast(pointer, byte_pointer), i32(0), i32(3), i32(1)])
        return context.get_dummy_value()

    return sig, codegen
