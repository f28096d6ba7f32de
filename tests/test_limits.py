"""backends.limits at its edges: the checks made before anything is
allocated or launched. The values are the documented ones, written out
(65536 a side; a pixel 3 colour bytes and a 4-byte hit index; a sphere 7
float32), not read from the module, so a changed constant fails."""

import pytest

from raybench import RaybenchError
from raybench.backends import limits


@pytest.mark.parametrize("width,height", [(1, 1), (65536, 1), (1, 65536), (65536, 65536)])
def test_sizes_up_to_65536_a_side_are_taken(width, height):
    assert limits.check_size(width, height) == (width, height)


@pytest.mark.parametrize(
    "width,height,name", [(0, 1, "width"), (65537, 1, "width"), (1, 0, "height"), (1, 65537, "height")]
)
def test_sizes_past_the_edges_are_refused(width, height, name):
    with pytest.raises(RaybenchError, match=f"^size: {name} must be an integer from 1 to 65536, got "):
        limits.check_size(width, height)


def test_rows_may_start_at_the_top_and_end_at_the_bottom():
    assert limits.check_rows((0, 10), 10) == (0, 10)
    assert limits.check_rows((9, 10), 10) == (9, 10)
    assert limits.check_rows((8, 16), 16, align=8) == (8, 16)
    for bad, align in [((0, 11), 1), ((5, 5), 1), ((-1, 3), 1), ((3, 10), 8), ((6, 4), 1)]:
        with pytest.raises(RaybenchError, match="^rows: "):
            limits.check_rows(bad, 10, align)


def test_a_frame_that_does_not_fit_says_how_much_it_needs():
    need = 65536 * 65536 * (3 + 4) + 10 * 7 * 4
    limits.check_fits("cuda", 65536, 65536, 10, need)  # exactly enough
    with pytest.raises(RaybenchError) as info:
        limits.check_fits("cuda", 65536, 65536, 10, need - 1)
    assert str(info.value) == (
        "size: 65536x65536 with 10 spheres needs 28.00 GiB, more than the 28.00 GiB available on the cuda; "
        "choose a smaller size"
    )


@pytest.mark.parametrize(
    "spheres,available,per_sphere,needs,has",
    [(1000, 2**31, 4 * 2**20, "3.91 GiB", "2.00 GiB"), (10, 1.5 * 2**20, 2**20, "10.0 MiB", "1.5 MiB")],
)
def test_a_tree_that_does_not_fit_says_how_much_it_needs(spheres, available, per_sphere, needs, has):
    with pytest.raises(RaybenchError) as info:
        limits.check_bvh_fits("cpu", spheres, available, per_sphere)
    assert str(info.value) == (
        f"bvh: {spheres:,} spheres need {needs} for the BVH and the frame, more than the {has} available "
        "on the cpu; use fewer spheres or a smaller size"
    )
