#!/usr/bin/env bash
# Mitsuba 3 and Dr.Jit for the GPU lease's `mitsuba` step (gpu_lease.sh; peers.py mitsuba), pruned
# to what that step loads, into .mi/, with trimesh's wheel beside them (the icosphere's maker,
# which the GPU machine's image lacks): the machine has no internet, and the working tree that a
# lease carries, .whl/ (some 23 MiB) and .mi/ among it, must fit in 64 MiB. The two wheels as
# published are 60 and 5 MiB; pruned, some 21 MiB together (the `du` at the end says).
#
#   bash benchmarks/mitsuba_wheel.sh [FOLDER]    # FOLDER: the two wheels (default /tmp/whl_mi), e.g.
#   pip download mitsuba==3.9.1 drjit==1.5.0 --no-deps --only-binary=:all: --python-version 3.12 \
#       --platform manylinux_2_28_x86_64 -d /tmp/whl_mi
#
# Each wheel is written again without the dropped files, with a RECORD that lists what is left
# (its hashes and sizes), so that pip installs it as any other:
# - Mitsuba: its variants only MI_VARIANTS (default cuda_ad_rgb, which the lease runs; add
#   llvm_ad_rgb, 1.3 MiB more, to check a pruned set on a CPU; config.py lists those kept), its
#   plugins only MI_PLUGINS (default: those that a run of peers.py mitsuba mapped into its process,
#   as /proc/self/maps showed: the scene's shape (ply, through merge), sensor, film, filter,
#   sampler and integrator, and the default BSDF and its texture that a shape without one is
#   given), none of its data files (the spectral upsampling table, sky models, IOR tables: the RGB
#   variant's run opened none), no headers, CMake files or type stubs. Its libraries all stay:
#   each variant links libmitsuba, which links Embree (on OptiX too) and OpenEXR.
# - Dr.Jit: no headers, CMake files or type stubs.
set -euo pipefail
FOLDER=$(realpath -m "${1:-/tmp/whl_mi}")
OUTDIR=$(realpath -m "${MI_OUT:-$(dirname "$0")/../.mi}")
for name in mitsuba drjit; do
    if [ "$(compgen -G "$FOLDER/$name-*.whl" | wc -l)" != 1 ]; then
        echo "mitsuba_wheel.sh: $FOLDER: needs one $name-*.whl" >&2
        exit 2
    fi
done
mkdir -p "$OUTDIR"
MI_VARIANTS=${MI_VARIANTS:-cuda_ad_rgb} \
MI_PLUGINS=${MI_PLUGINS:-aov box diffuse hdrfilm merge perspective ply stratified uniform} \
python3 - "$FOLDER" "$OUTDIR" <<'EOF'
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
            sys.exit(f"mitsuba_wheel.sh: {os.path.basename(wheel)} has no {', '.join(missing)}")
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
                        sys.exit("mitsuba_wheel.sh: mitsuba/config.py names no MI_VARIANTS")
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
if compgen -G "$FOLDER/trimesh-4.12.2-*.whl" > /dev/null; then
    cp "$FOLDER"/trimesh-4.12.2-*.whl "$OUTDIR"/
else
    python3 -m pip download -q --no-deps --only-binary=:all: -d "$OUTDIR" 'trimesh==4.12.2'
fi
du -ch "$OUTDIR"/*.whl | tail -1
