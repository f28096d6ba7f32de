#!/usr/bin/env bash
# What gpu_lease.sh needs carried to the GPU machine (its Python is 3.12 on x86_64, with
# numba-cuda and NumPy 2.5, and no internet), made on this side, one part a call; then carry
# the folders made: run's carry [".whl", ".gl"] (and ".pov", ".mi"); the limit is 64 MiB with
# the tree.
#
#   bash benchmarks/lease_wheels.sh [wheels] [--povray] && du -sh .whl .gl .pov
#   bash benchmarks/lease_wheels.sh dask && ls .whl
#   bash benchmarks/lease_wheels.sh embreex && ls .emb
#   bash benchmarks/lease_wheels.sh mitsuba [FOLDER]
#
# wheels (the default):
#   .whl  NumPy 2.4 (2.5 breaks numba 0.68), and raybench's dependencies the machine lacks: orjson
#         (the results reader), wgpu, cffi, pycparser, rendercanvas, glfw, platformdirs, filelock,
#         trimesh (meshes), gemmi (molecules), mapbox-earcut (NFF's concave polygons);
#   .gl   the Vulkan and GL loaders as Debian packages (with them wgpu finds the GPU through
#         NVIDIA's Vulkan driver);
#   .pov  with --povray: POV-Ray 3.7 from Debian's povray package, its binary and the shared
#         libraries it links beyond the C library, as .pov/povray.tar.xz (unpacked, it would pass
#         the carry's limit with the rest); gpu_lease.sh's povray step unpacks it and runs
#         peers.py povray with it.
# dask: the wheels raybench.cluster needs, into .whl/, for the multigpu step. The issue's probe
#   carried dask, distributed, tornado, tblib, zict, partd and locket; the rest of their
#   dependencies are carried too, so that nothing depends on what the machine happens to have
#   (each is small). Dask and distributed at the versions tested (distributed pins its dask
#   exactly).
# mitsuba: Mitsuba 3 and Dr.Jit for the `mitsuba` step (peers.py mitsuba), pruned to what that
#   step loads, into .mi/ (MI_OUT to write elsewhere), with trimesh's wheel beside them (the
#   icosphere's maker, which the GPU machine's image lacks): as published the two wheels alone
#   would pass the carry's limit with .whl/ (the `du` at the end says what is left). FOLDER holds
#   the two wheels (default /tmp/whl_mi), e.g.
#     pip download mitsuba==3.9.1 drjit==1.5.0 --no-deps --only-binary=:all: --python-version 3.12 \
#         --platform manylinux_2_28_x86_64 -d /tmp/whl_mi
#   Each wheel is written again without the dropped files, with a RECORD that lists what is left
#   (its hashes and sizes), so that pip installs it as any other:
#   - Mitsuba: its variants only MI_VARIANTS (default cuda_ad_rgb, which the lease runs; add
#     llvm_ad_rgb to check a pruned set on a CPU; config.py lists those kept), its plugins only
#     MI_PLUGINS (default: those that a run of peers.py mitsuba mapped into its process, as
#     /proc/self/maps showed: the scene's shape (ply, through merge), sensor, film, filter,
#     sampler and integrator, and the default BSDF and its texture that a shape without one is
#     given), none of its data files (the spectral upsampling table, sky models, IOR tables: the
#     RGB variant's run opened none), no headers, CMake files or type stubs. Its libraries all
#     stay: each variant links libmitsuba, which links Embree (on OptiX too) and OpenEXR.
#   - Dr.Jit: no headers, CMake files or type stubs.
set -euo pipefail
ROOT=$(realpath "$(dirname "$0")/..")

# Binary wheels for the GPU machine's Python into .whl/: the one download both wheel sets take.
download() {
    mkdir -p "$ROOT/.whl"
    python3 -m pip download -q --only-binary=:all: --no-deps --python-version 3.12 \
        --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux_2_28_x86_64 \
        --implementation cp -d "$ROOT/.whl" "$@"
}

part_wheels() {
    download 'numpy>=2.4,<2.5' 'orjson>=3.10,<4' 'wgpu>=0.32,<0.33' 'cffi>=1.15' 'pycparser' \
        'rendercanvas>=2.7,<3' 'glfw>=2.11,<3' 'platformdirs>=4.14,<5' 'filelock>=3.32,<4' 'trimesh>=4.12,<5' \
        'gemmi>=0.7,<0.8' 'mapbox-earcut>=2.1,<3'
    mkdir -p "$ROOT/.gl"
    (cd "$ROOT/.gl" && apt-get download libvulkan1 libglvnd0 libgl1 libglx0 libegl1 libopengl0 >/dev/null)
}

part_povray() {
    command -v povray >/dev/null || { echo "lease_wheels.sh: povray is not installed (apt-get install povray)" >&2; exit 2; }
    local stage
    stage=$(mktemp -d) && mkdir -p "$stage/bin" "$stage/lib" && cp "$(command -v povray)" "$stage/bin/"
    for lib in $(ldd "$(command -v povray)" | awk '{print $3}' | grep '^/'); do
        case $(basename "$lib") in libc.so* | libm.so* | libpthread* | libdl.so* | ld-linux* | librt*) ;;
            *) cp -L "$lib" "$stage/lib/" ;; esac
    done
    rm -rf "$ROOT/.pov" && mkdir -p "$ROOT/.pov" && tar -C "$stage" -cJf "$ROOT/.pov/povray.tar.xz" bin lib
    rm -rf "$stage"
}

part_dask() {
    download 'dask==2026.8.0' 'distributed==2026.8.0' 'tornado>=6.2' 'tblib>=1.6,!=3.2.0,!=3.2.1' 'zict>=3' \
        'partd>=1.4' 'locket>=1' 'cloudpickle>=3' 'toolz>=0.12' 'msgpack>=1.0.2' 'sortedcontainers>=2.0.5' \
        'pyyaml>=5.4.1' 'fsspec>=2021.9' 'jinja2>=2.10.3' 'markupsafe>=2' 'click>=8.1' 'psutil>=5.9' 'packaging>=20' \
        'xxhash>=4.1,<5'
    ls "$ROOT/.whl" | grep -iE 'dask|distributed|tornado|tblib|zict|partd|locket|cloudpickle|toolz|msgpack|yaml|fsspec|jinja|xxhash'
}

# embreex (Embree 4) for the `embreex` step (peers.py embreex on the GPU machine's host cores), into .emb/
part_embreex() {
    mkdir -p "$ROOT/.emb"
    python3 -m pip download -q --only-binary=:all: --no-deps --python-version 3.12 \
        --platform manylinux_2_28_x86_64 --implementation cp -d "$ROOT/.emb" 'embreex==4.4.0.post1'
}

part_mitsuba() {
    local folder outdir name
    folder=$(realpath -m "${1:-/tmp/whl_mi}")
    outdir=$(realpath -m "${MI_OUT:-$ROOT/.mi}")
    for name in mitsuba drjit; do
        if [ "$(compgen -G "$folder/$name-*.whl" | wc -l)" != 1 ]; then
            echo "lease_wheels.sh mitsuba: $folder: needs one $name-*.whl" >&2
            exit 2
        fi
    done
    mkdir -p "$outdir"
    MI_VARIANTS=${MI_VARIANTS:-cuda_ad_rgb} \
    MI_PLUGINS=${MI_PLUGINS:-aov box diffuse hdrfilm merge perspective ply stratified uniform} \
    python3 - "$folder" "$outdir" <<'EOF'
import base64, glob, hashlib, os, re, sys, zipfile

folder, outdir = sys.argv[1:3]
variants = os.environ["MI_VARIANTS"].split()
plugins = {f"mitsuba/plugins/{name}.so" for name in os.environ["MI_PLUGINS"].split()}
ALL_VARIANTS = re.compile(r"mitsuba/(scalar|llvm_ad|cuda_ad)_\w+\.cpython-\d+-[\w-]+\.so$")


def kept(name: str) -> bool:
    if name.endswith(".pyi") or "/include/" in name or "/cmake/" in name or "/pkgconfig/" in name:
        return False
    if name.startswith(("mitsuba/mitsuba_stubs/", "mitsuba/data/", "drjit/stubs.pat")):
        return False
    if name.startswith("mitsuba/plugins/"):
        return name in plugins
    if ALL_VARIANTS.match(name):
        return any(name.startswith(f"mitsuba/{v}.cpython-") for v in variants)
    return True


def record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


for wheel in sorted(glob.glob(os.path.join(folder, "mitsuba-*.whl")) + glob.glob(os.path.join(folder, "drjit-*.whl"))):
    out = os.path.join(outdir, os.path.basename(wheel))
    with zipfile.ZipFile(wheel) as src:
        record = next(n for n in src.namelist() if n.endswith(".dist-info/RECORD"))
        missing = sorted(p for p in plugins if wheel.startswith(os.path.join(folder, "mitsuba-")) and p not in src.namelist())
        if missing:
            sys.exit(f"lease_wheels.sh mitsuba: {os.path.basename(wheel)} has no {', '.join(missing)}")
        lines, dropped = [], 0
        with zipfile.ZipFile(out + ".part", "w", zipfile.ZIP_DEFLATED, compresslevel=9) as dst:
            for info in src.infolist():
                name = info.filename
                if name == record or name.endswith("/"):
                    continue
                if not kept(name):
                    dropped += info.file_size
                    continue
                data = src.read(info)
                if name == "mitsuba/config.py":  # the variants it lists are the ones left
                    data, found = re.subn(rb"MI_VARIANTS = \[.*?\]", b"MI_VARIANTS = %r" % variants, data, count=1)
                    if not found:
                        sys.exit("lease_wheels.sh mitsuba: mitsuba/config.py names no MI_VARIANTS")
                copy = zipfile.ZipInfo(name, info.date_time)
                copy.external_attr = info.external_attr
                dst.writestr(copy, data, zipfile.ZIP_DEFLATED, 9)
                lines.append(record_line(name, data))
            lines.append(f"{record},,")
            dst.writestr(zipfile.ZipInfo(record, (2026, 1, 1, 0, 0, 0)), "\n".join(lines) + "\n")
    os.replace(out + ".part", out)  # whole or not at all
    print(f"{os.path.basename(out)}: {os.path.getsize(wheel) / 2**20:.1f} MiB -> {os.path.getsize(out) / 2**20:.1f} MiB "
          f"({dropped / 2**20:.0f} MiB unpacked dropped)")
EOF
    # trimesh at raybench's pin (pyproject.toml), pure Python, NumPy its one dependency: FOLDER's, else PyPI's
    if compgen -G "$folder/trimesh-4.12.2-*.whl" > /dev/null; then
        cp "$folder"/trimesh-4.12.2-*.whl "$outdir"/
    else
        python3 -m pip download -q --no-deps --only-binary=:all: -d "$outdir" 'trimesh==4.12.2'
    fi
    du -ch "$outdir"/*.whl | tail -1
}

usage() {
    echo "usage: lease_wheels.sh [wheels] [--povray] | dask | embreex | mitsuba [FOLDER]" >&2
    exit 2
}

case "$*" in
    "" | wheels) part_wheels ;;
    --povray | "wheels --povray") part_wheels && part_povray ;;
    dask) part_dask ;;
    embreex) part_embreex ;;
    mitsuba | "mitsuba "*) shift; [ $# -le 1 ] || usage; part_mitsuba "$@" ;;
    *) usage ;;
esac
