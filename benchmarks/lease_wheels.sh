#!/usr/bin/env bash
# What gpu_lease.sh needs carried to the GPU machine (its Python is 3.12 on x86_64, with
# numba-cuda and NumPy 2.5, and no internet), made on this side:
#   .whl  NumPy 2.4 (2.5 breaks numba 0.68), and raybench's dependencies the machine lacks: orjson
#         (the results reader), wgpu, cffi, pycparser, rendercanvas, glfw, platformdirs, filelock,
#         trimesh (meshes), gemmi (molecules), mapbox-earcut (NFF's concave polygons);
#   .gl   the Vulkan and GL loaders as Debian packages (with them wgpu finds the GPU through
#         NVIDIA's Vulkan driver);
#   .pov  with --povray: POV-Ray 3.7 from Debian's povray package, its binary and the shared
#         libraries it links beyond the C library, as .pov/povray.tar.xz (7.5 MB; 27 MB unpacked,
#         which with the rest would pass the carry's limit); gpu_lease.sh's povray step unpacks
#         it and runs peers.py povray with it.
# Then carry them: run's carry [".whl", ".gl"] (and ".pov"); the limit is 64 MiB with the tree.
#   bash benchmarks/lease_wheels.sh [--povray] && du -sh .whl .gl .pov
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p .whl .gl
python3 -m pip download -q --only-binary=:all: --no-deps --python-version 3.12 \
    --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux_2_28_x86_64 \
    --implementation cp -d .whl \
    'numpy>=2.4,<2.5' 'orjson>=3.10,<4' 'wgpu>=0.32,<0.33' 'cffi>=1.15' 'pycparser' 'rendercanvas>=2.7,<3' \
    'glfw>=2.11,<3' 'platformdirs>=4.14,<5' 'filelock>=3.32,<4' 'trimesh>=4.12,<5' 'gemmi>=0.7,<0.8' \
    'mapbox-earcut>=2.1,<3'
(cd .gl && apt-get download libvulkan1 libglvnd0 libgl1 libglx0 libegl1 libopengl0 >/dev/null)
if [ "${1:-}" = "--povray" ]; then
    command -v povray >/dev/null || { echo "lease_wheels.sh: povray is not installed (apt-get install povray)" >&2; exit 2; }
    stage=$(mktemp -d) && mkdir -p "$stage/bin" "$stage/lib" && cp "$(command -v povray)" "$stage/bin/"
    for lib in $(ldd "$(command -v povray)" | awk '{print $3}' | grep '^/'); do
        case $(basename "$lib") in libc.so* | libm.so* | libpthread* | libdl.so* | ld-linux* | librt*) ;;
            *) cp -L "$lib" "$stage/lib/" ;; esac
    done
    rm -rf .pov && mkdir -p .pov && tar -C "$stage" -cJf .pov/povray.tar.xz bin lib && rm -rf "$stage"
fi
