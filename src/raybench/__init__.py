"""raybench: one ray-tracing algorithm, written once in Python, compiled for the
CPU (Numba) and for NVIDIA GPUs (numba-cuda), to measure what a GPU buys."""

from .camera import Camera
from .errors import RaybenchError
from .lighting import Light, Material
from .render import Frame, Renderer, render
from .scene import Scene, random_spheres
from .scene_meshes import SceneMesh

__version__ = "0.1.0"

__all__ = [
    "Camera",
    "Frame",
    "Light",
    "Material",
    "RaybenchError",
    "Renderer",
    "Scene",
    "SceneMesh",
    "random_spheres",
    "render",
    "__version__",
]
