"""Real scenes on every device, held to the float64 reference (issue 38's
correctness target): the SPD's sphereflake on its floor, the shipped
molecule 1TII drawn as spheres, and a chain of it drawn ball-and-stick
(spheres and the sticks' triangles in one tree). Each frame's hits are
test_mixed's float64 nearest hit over both kinds on every pixel clear of an
outline or a tie: all of them on the cpu, under numba's CUDA simulator and
on a CPU adapter (every operation rounded to float32 as the reference's
twins are), 99.5% on a GPU, whose compiler may fuse a product into a sum
and tip a ray at a hair from an outline.

The cpu's frames of the mixed kind are left to test_mixed and
test_molecule_styles (its first compile takes minutes); here the cpu draws
the molecule of spheres, and cuda and wgpu draw all three."""

from __future__ import annotations

import numpy as np
import pytest
from test_mixed import both_reference, sphere_reference
from test_mixed_wgpu import balls, on_cpu
from test_molecule_styles import tiny
from test_triangle_render import rays64

from raybench import render
from raybench.backends import cuda as cuda_backend
from raybench.examples import path as example
from raybench.formats import fit_camera, molecule

SIM = cuda_backend.simulated()
ATOMS = 600  # of 1TII's 5,469: the float64 reference tests every ray against every sphere


def sphereflake(tmp_path):
    return balls()


def spacefill(tmp_path):
    """1TII's first ATOMS atoms as van der Waals spheres, framed as a molecule is (fit_camera)."""
    from importlib import resources

    with resources.as_file(example("1tii")) as path:
        part = molecule.load(path).head(ATOMS)
    return part.replaced(camera=fit_camera(part.centers, part.radii))


def ball_and_stick(tmp_path):
    """Chain D of test_molecule_styles' small molecule, balls and sticks."""
    path = tmp_path / "chain.pdb"
    path.write_text("\n".join([line for line in tiny() if line[21] == "D"] + ["END", ""]))
    return molecule.load(path, style="ball-and-stick")


SCENES = {"balls 2 on its floor": sphereflake, "1TII as spheres": spacefill, "a ball-and-stick chain": ball_and_stick}


def agreement(scene, frame, width, height) -> float:
    """The share of clear pixels whose hit is the float64 reference's; at
    least 20 of them on something (the scene is in the frame)."""
    if scene.triangles is None:  # spheres alone: their reference, clear of an outline
        index, _t, margin = sphere_reference(scene.spheres, *rays64(scene.camera, width, height))
        clear = (index < 0) | (margin > 1e-4)
    else:
        index, _t, clear, _o, _d = both_reference(scene, width, height)
    assert (clear & (index >= 0)).sum() > 20
    return (frame.hits.ravel()[clear] == index[clear]).mean()


@pytest.mark.parametrize("which", list(SCENES))
@pytest.mark.gpu
@pytest.mark.skipif(not cuda_backend.available(), reason="no CUDA GPU and the simulator is off")
def test_cuda_hits_the_float64_reference(which, tmp_path):
    scene = SCENES[which](tmp_path)
    width, height = (40, 28) if SIM else (160, 120)
    frame = render(scene, None, width, height, device="cuda")
    assert frame.device == "cuda"
    assert agreement(scene, frame, width, height) >= (1.0 if SIM else 0.995)


@pytest.mark.parametrize("which", list(SCENES))
@pytest.mark.gpu
def test_wgpu_hits_the_float64_reference(which, tmp_path, adapter):
    scene = SCENES[which](tmp_path)
    frame = render(scene, None, 64, 48, device="wgpu", adapter=adapter)
    assert frame.device == "wgpu"
    got = agreement(scene, frame, 64, 48)
    assert got == 1.0 if on_cpu(adapter) else got >= 0.995


def test_cpu_hits_the_float64_reference_on_a_molecule(tmp_path):
    scene = spacefill(tmp_path)
    assert len(scene) == ATOMS and scene.traced().kind == "sphere"
    frame = render(scene, None, 96, 64, device="cpu", threads=2)
    assert np.isclose(agreement(scene, frame, 96, 64), 1.0)
