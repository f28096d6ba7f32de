#!/usr/bin/env bash
# One lease of the GPU machine (device tool): the steps named in STEPS, in
# order, each with its own time limit, so that the run ends inside the
# lease's 10 minutes and everything it wrote comes back as one archive,
# $OUT/lease.tar.gz (its steps.log says how each step ended).
#
#   info     nvidia-smi, raybench info (the CUDA device and the wgpu adapters)
#   pytest   the tests that can run without a window (-m "not window"): every
#            GPU test (marker gpu) and the CPU ones, the BVH build's on 16 threads
#            among them; PYTEST_ARGS to change, e.g. PYTEST_ARGS="-m gpu" for the
#            GPU tests alone
#   kernels  benchmarks/kernels.py: measured peaks, simple against fast kernels (KERNELS_ARGS to
#            change); with BASELINE (and BASELINE_COMMITS) as builds
#   trip     the CUDA fast kernel's spheres per trip of its cull loop (kernels.py --sweep-trip)
#   scaling  the scaling suite, 10 to 1,000,000 spheres (SCALING_DEVICES)
#   thesis   the thesis suite, fast kernels and the BVH, cuda and cpu
#   wgpu     the thesis suite on wgpu, BVH and brute force (WGPU_ARGS to change)
#   secondary the secondary suite (Whitted's rays and the thesis's beside them), cuda and cpu through
#            the BVH (SECONDARY_ARGS to change)
#   tuning   the BVH walk's block shapes on cuda
#   walks    benchmarks/bvh_walks.py on cuda and wgpu (WALKS_ARGS to change); with
#            BASELINE="dir ..." (other versions' src/, carried; their commits in
#            BASELINE_COMMITS, in the same order), those versions and this one in
#            turn, twice, side by side in one lease
#   builds   benchmarks/bvh_build.py (BUILDS_ARGS to change), with BASELINE (and BASELINE_COMMITS) as walks
#   whitted  benchmarks/whitted_rays.py: Whitted shading's rays a second (WHITTED_ARGS to change); with
#            BASELINE (and BASELINE_COMMITS, as startup), those versions and this one in turn,
#            WHITTED_ROUNDS times (2)
#   viewer   benchmarks/viewer_frames.py: the viewer's Whitted frames a second with no window (its own
#            draws into an offscreen texture; no present), at 1,000 and 10,000 spheres, its records in
#            viewer.jsonl (VIEWER_ARGS to change)
#   warmup   raybench warmup on cuda (its BVH builder included): the kernels into the disk cache, which
#            every later process (a cluster's workers among them) loads
#   multigpu benchmarks/multi_gpu.py: 1 and 2 cuda workers of raybench.cluster on a
#            240-frame orbit at 1680x1050, an 8192x8192 frame in tiles, both at 100,000
#            spheres, and the scaling model's terms (MULTIGPU_ARGS to change); needs the
#            Dask wheels in .whl (benchmarks/lease_wheels.sh dask) and the machine kind nvidia-h200-x2
#   multibench raybench bench --suite multi-gpu on cuda: the same throughput as results
#            records, for raybench report's section across workers
#   dynamic  the dynamic suite: moving spheres, the tree's update and the frame, cuda (both builds),
#            cpu and wgpu (DYNAMIC_ARGS to change)
#   meshes   the meshes suite: an icosphere and random triangles, 10 thousand to 10 million, primary
#            and Whitted rays, cuda, cpu and wgpu (MESHES_ARGS to change, e.g. one device a lease)
#   scenes   the scenes suite: the SPD's scenes at size factors 1 to 6, Whitted, cuda, wgpu and cpu
#            (SCENES_ARGS to change, e.g. one device a lease; SCENES_S its limit, 500 s)
#   povray   benchmarks/peers.py povray: POV-Ray 3.7 on the host's cores against raybench on each of
#            POVRAY_DEVICES (cpu cuda), the same SPD scenes; needs .pov (benchmarks/lease_wheels.sh
#            --povray); records in povray-DEVICE.jsonl (POVRAY_ARGS to change the scenes and frames)
#   startup  benchmarks/startup.py: the time to the first picture, cold and warm, each version of
#            BASELINE (with its commit, BASELINE_COMMITS in the same order) then this one, on the
#            cores STARTUP_CPUS (taskset -c; e.g. 0,1 for two) where set (STARTUP_ARGS to change)
#   gpubuild benchmarks/gpu_build.py: the BVH built on the GPU against the host's binned SAH tree
#            (build, refit, SAH cost, walks on both, leaf sizes), its records in gpu-build.json
#            (GPUBUILD_ARGS to change, e.g. "--spheres 100000 --repeats 101")
#   meshbuild benchmarks/mesh_build.py: the GPU builds over a mesh's triangles (cuda, wgpu, the host's beside
#            them) and a 10M-triangle frame's peak memory beyond the mesh (cuda, cpu), its records in
#            mesh-build.jsonl (MESHBUILD_ARGS to change)
#   wgpubuild benchmarks/wgpu_build.py: the same BVH built in WGSL through wgpu (build by step,
#            refit, SAH cost, the walk on both trees), its records in wgpu-build.json
#            (WGPUBUILD_ARGS to change)
#   mitsuba  benchmarks/peers.py mitsuba --variant cuda_ad_rgb --device cuda: raybench's cuda frames of
#            an icosphere against Mitsuba 3 on OptiX, the same rays, side by side; needs .mi (the pruned
#            wheels of benchmarks/lease_wheels.sh mitsuba), installed into /tmp/site-mi; its records and log in
#            $W/mitsuba/ (MITSUBA_ARGS added after those flags, e.g. "--subdivisions 8 --rounds 3";
#            MITSUBA_S its limit, 240 s)
#   embreex  benchmarks/peers.py embreex: raybench's cpu frames of an icosphere against Embree 4 through
#            embreex on the host's cores, the same rays; needs .emb (lease_wheels.sh embreex), installed
#            into /tmp/site-emb; records and log in $W/embreex/ (EMBREEX_ARGS, default
#            "--subdivisions 6 8"; EMBREEX_S its limit, 300 s)
#
# An archived script (benchmarks/archive/, its README) has no step: STEPS="" installs the wheels into
# /tmp/site, then run it by hand with benchmarks/ on PYTHONPATH for _harness, e.g.
#   RAYBENCH_GIT_COMMIT=<commit> STEPS="" bash benchmarks/gpu_lease.sh &&
#       RAYBENCH_GIT_COMMIT=<commit> PYTHONPATH=/tmp/site:$PWD/src:$PWD/benchmarks \
#       python3 benchmarks/archive/wgpu_readback.py
#
# Carries .whl (NumPy 2.4: the machine's 2.5 breaks numba 0.68.0; orjson, which the results reader imports; wgpu, cffi,
# pycparser, rendercanvas, glfw) and .gl (the Vulkan and GL loaders as Debian
# packages; with them wgpu finds the GPU through NVIDIA's Vulkan driver):
#   RAYBENCH_GIT_COMMIT=<commit> LABEL=h200 STEPS="info pytest kernels" bash benchmarks/gpu_lease.sh
#
# RAYBENCH_GIT_COMMIT is required: the machine's copy of the checkout carries
# stale git metadata, so every record would name a wrong commit. Write the value
# out on this side (`git describe --always --dirty --abbrev=12` here), not as
# $(git ...) in the command, which would run there, on the stale metadata.
set -uo pipefail
if [ -z "${RAYBENCH_GIT_COMMIT:-}" ]; then
    echo "gpu_lease.sh: set RAYBENCH_GIT_COMMIT to the commit that runs (git describe --always --dirty --abbrev=12 here)" >&2
    exit 2
fi
export RAYBENCH_GIT_COMMIT
# Bytecode compiled at install, as pip does by default: without it every process compiled the
# carried packages from source, which a real install never does (369 modules, 0.6 s of a warm
# render's start under a profiler, lease y2).
python3 -m pip install -q --no-index --no-deps --no-cache-dir --upgrade --target /tmp/site .whl/*.whl || exit 1
if [ -d .gl ]; then for f in .gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
export PYTHONPATH=/tmp/site:$PWD/src PYTHONUNBUFFERED=1
OUT=${OUT:-/tmp/out}; W=/tmp/lease; rm -rf "$W"; mkdir -p "$W" "$OUT"
LABEL=${LABEL:-h200}; DURATION=${DURATION:-1}
echo "$RAYBENCH_GIT_COMMIT" > "$W/git_commit.txt"
# STEPS unset: the steps below; STEPS="": none (the wheels installed, for commands of ones own after)
STEPS=${STEPS-info pytest kernels scaling thesis wgpu tuning}
step() {  # step NAME SECONDS COMMAND...: its output to $W/NAME.log, how it ended to steps.log
    local name=$1 limit=$2 n=2; shift 2
    local t0=$SECONDS
    # a step named twice in STEPS (more rounds of one comparison) keeps each run's log: NAME.2, ...
    if [ -e "$W/$name.log" ]; then while [ -e "$W/$name.$n.log" ]; do n=$((n + 1)); done; name=$name.$n; fi
    timeout -s INT "$limit" "$@" > "$W/$name.log" 2>&1
    echo "$name rc=$? $((SECONDS - t0)) s" | tee -a "$W/steps.log"
}
bench() {  # bench NAME SECONDS ARGS...: raybench bench, its results in $W/NAME/
    local name=$1 limit=$2; shift 2
    step "$name" "$limit" python3 -m raybench bench --no-report --label "$LABEL" --out "$W/$name" --duration "$DURATION" "$@"
}
baselines() {  # baselines STEP SECONDS LABEL COMMAND...: COMMAND under each version of BASELINE in turn
    # (a version's src/ folder, named by the folder above it; its commit the same place in
    # BASELINE_COMMITS), as step STEP (a printf pattern, %s the version's name), with
    # --label LABEL-name added where LABEL is not empty
    local pattern=$1 limit=$2 label=$3; shift 3
    local commits=(${BASELINE_COMMITS:-}) i=0 base name
    for base in ${BASELINE:-}; do
        name=${base%/}; name=${name%/src}; name=${name##*/}
        # shellcheck disable=SC2059
        step "$(printf "$pattern" "$name")" "$limit" env PYTHONPATH="/tmp/site:$PWD/$base" \
            RAYBENCH_GIT_COMMIT="${commits[$i]:-unknown}" "$@" ${label:+--label "$label-$name"}
        i=$((i + 1))
    done
}
side_by_side() {  # side_by_side NAME SECONDS COMMAND...: with BASELINE, each of its versions then this
    # one, two rounds; without, this one once; steps NAME-<version>-<round> and NAME-<round>
    local name=$1 limit=$2 round; shift 2
    for round in $([ -n "${BASELINE:-}" ] && echo 1 2 || echo 1); do
        baselines "$name-%s-$round" "$limit" "$name" "$@"
        step "$name-$round" "$limit" "$@" --label "$name"
    done
}
for s in $STEPS; do
    case $s in
    info)
        nvidia-smi --query-gpu=name,driver_version,clocks.max.sm,memory.total --format=csv > "$W/nvidia-smi.txt" 2>&1
        step info 60 python3 -m raybench info
        python3 -m raybench info --json > "$W/info.json" 2>/dev/null ;;
    pytest)
        # PYTEST_ARGS is read as shell words, so that a marker expression can be quoted in it
        eval "pytest_args=(${PYTEST_ARGS:--m \"not window\"})"
        step pytest "${PYTEST_S:-300}" python3 -m pytest -q -p no:cacheprovider "${pytest_args[@]}" ;;
    # shellcheck disable=SC2086
    kernels) side_by_side kernels "${KERNELS_S:-80}" python3 benchmarks/kernels.py --out "$W/kernels.jsonl" \
        --frames 7 ${KERNELS_ARGS:-} ;;
    trip) step trip "${TRIP_S:-120}" python3 benchmarks/kernels.py --out "$W/trip.jsonl" --frames 7 --skip-peak \
            --sweep-trip ;;
    scaling)
        # shellcheck disable=SC2086
        bench scaling "${SCALING_S:-200}" --suite scaling $(printf -- '--device %s ' ${SCALING_DEVICES:-cuda cpu}) \
            ${SCALING_ARGS:-} ;;
    thesis) bench thesis "${THESIS_S:-200}" --suite thesis --device cuda --device cpu ${THESIS_ARGS:-} ;;
    # shellcheck disable=SC2086
    wgpu) bench wgpu "${WGPU_S:-150}" ${WGPU_ARGS:---suite thesis --device wgpu} ;;
    # shellcheck disable=SC2086
    secondary) bench secondary "${SECONDARY_S:-300}" ${SECONDARY_ARGS:---suite secondary --device cuda --device cpu --accel bvh} ;;
    tuning) bench tuning "${TUNING_S:-50}" --suite tuning --accel bvh --device cuda ;;
    # shellcheck disable=SC2086
    meshes) bench meshes "${MESHES_S:-480}" ${MESHES_ARGS:---suite meshes --device cuda --device cpu --device wgpu} ;;
    # shellcheck disable=SC2086
    scenes) bench scenes "${SCENES_S:-500}" ${SCENES_ARGS:---suite scenes --device cuda --device wgpu --device cpu} ;;
    povray)
        # POV-Ray 3.7 carried as .pov/povray.tar.xz (benchmarks/lease_wheels.sh --povray), its libraries
        # seen by it alone (a wrapper): Python's own must stay the machine's
        mkdir -p /tmp/pov/wrap && tar -C /tmp/pov -xJf .pov/povray.tar.xz &&
            printf '#!/bin/sh\nLD_LIBRARY_PATH=/tmp/pov/lib exec /tmp/pov/bin/povray "$@"\n' > /tmp/pov/wrap/povray &&
            chmod +x /tmp/pov/wrap/povray
        for device in ${POVRAY_DEVICES:-cpu cuda}; do
            # shellcheck disable=SC2086
            step "povray-$device" "${POVRAY_S:-300}" env PATH="/tmp/pov/wrap:$PATH" python3 benchmarks/peers.py povray \
                --device "$device" --out "$W/povray-$device.jsonl" ${POVRAY_ARGS:---scenes balls:4 balls:5 --frames 3 --rounds 2}
        done ;;
    walks)
        for round in 1 2; do
            # shellcheck disable=SC2086
            baselines "walks-%s-$round" "${WALKS_S:-60}" walks python3 benchmarks/bvh_walks.py \
                ${WALKS_ARGS:---device cuda --device wgpu}
            # shellcheck disable=SC2086
            step "walks-$round" "${WALKS_S:-60}" python3 benchmarks/bvh_walks.py --label walks \
                ${WALKS_ARGS:---device cuda --device wgpu}
        done ;;
    builds)
        for round in 1 2; do
            # shellcheck disable=SC2086
            baselines "builds-%s-$round" "${BUILDS_S:-90}" "" python3 benchmarks/bvh_build.py \
                ${BUILDS_ARGS:---threads 1 --threads 4 --threads 16}
            # shellcheck disable=SC2086
            step "builds-$round" "${BUILDS_S:-90}" python3 benchmarks/bvh_build.py \
                ${BUILDS_ARGS:---threads 1 --threads 4 --threads 16}
        done ;;
    whitted)
        if [ -z "${BASELINE:-}" ]; then
            # shellcheck disable=SC2086
            step whitted "${WHITTED_S:-200}" python3 benchmarks/whitted_rays.py \
                ${WHITTED_ARGS:---device cuda --device wgpu --device cpu}
        else  # side by side: each version of BASELINE (its commit in BASELINE_COMMITS) then this one, in turn
            for round in $(seq "${WHITTED_ROUNDS:-2}"); do
                # shellcheck disable=SC2086
                baselines "whitted-%s-$round" "${WHITTED_S:-200}" whitted python3 benchmarks/whitted_rays.py \
                    ${WHITTED_ARGS:---device cuda --device wgpu}
                # shellcheck disable=SC2086
                step "whitted-$round" "${WHITTED_S:-200}" python3 benchmarks/whitted_rays.py --label whitted \
                    ${WHITTED_ARGS:---device cuda --device wgpu}
            done
        fi ;;
    viewer)
        # shellcheck disable=SC2086
        step viewer "${VIEWER_S:-300}" python3 benchmarks/viewer_frames.py --out "$W/viewer.jsonl" \
            ${VIEWER_ARGS:---device cuda --device wgpu --spheres 1000 --spheres 10000 --size 1680x1050} ;;
    warmup) step warmup "${WARMUP_S:-300}" python3 -m raybench warmup --device cuda ;;
    multigpu)
        # shellcheck disable=SC2086
        step multigpu "${MULTIGPU_S:-420}" python3 benchmarks/multi_gpu.py --out "$W/multi_gpu.jsonl" \
            ${MULTIGPU_ARGS:---device cuda --workers 1 --workers 2 --spheres 100000 --orbit 240 --orbit-size 1680x1050 --frame 8192x8192} ;;
    multibench) bench multibench "${MULTIBENCH_S:-400}" --suite multi-gpu --device cuda --accel bvh ;;
    # shellcheck disable=SC2086
    dynamic) bench dynamic "${DYNAMIC_S:-300}" ${DYNAMIC_ARGS:---suite dynamic --device cuda --device cpu --device wgpu} ;;
    startup)
        # shellcheck disable=SC2086
        baselines "startup-%s" "${STARTUP_S:-240}" "" ${STARTUP_CPUS:+taskset -c $STARTUP_CPUS} \
            python3 benchmarks/startup.py ${STARTUP_ARGS:---device cpu --frames 2}
        # shellcheck disable=SC2086
        step startup "${STARTUP_S:-240}" ${STARTUP_CPUS:+taskset -c $STARTUP_CPUS} \
            python3 benchmarks/startup.py ${STARTUP_ARGS:---device cpu --frames 2} ;;
    # shellcheck disable=SC2086
    gpubuild) side_by_side gpubuild "${GPUBUILD_S:-420}" python3 benchmarks/gpu_build.py \
        --out "$W/gpu-build.jsonl" ${GPUBUILD_ARGS:-} ;;
    # shellcheck disable=SC2086
    wgpubuild) side_by_side wgpubuild "${WGPUBUILD_S:-420}" python3 benchmarks/wgpu_build.py \
        --out "$W/wgpu-build.jsonl" ${WGPUBUILD_ARGS:-} ;;
    # shellcheck disable=SC2086
    meshbuild) step meshbuild "${MESHBUILD_S:-300}" python3 benchmarks/mesh_build.py --out "$W/mesh-build.jsonl" \
        ${MESHBUILD_ARGS:---device cuda --device wgpu --subdivisions 8 --random 1000000 --memory 10000000 --memory-device cuda --memory-device cpu} ;;
    mitsuba)
        mkdir -p "$W/mitsuba"
        python3 -m pip install -q --no-index --no-deps --no-cache-dir --upgrade --target /tmp/site-mi .mi/*.whl \
            > "$W/mitsuba/install.log" 2>&1 || echo "mitsuba: .mi/*.whl did not install (install.log)" | tee -a "$W/steps.log"
        # shellcheck disable=SC2086
        step mitsuba/mitsuba "${MITSUBA_S:-240}" env PYTHONPATH="/tmp/site-mi:$PYTHONPATH" python3 benchmarks/peers.py \
            mitsuba --variant cuda_ad_rgb --device cuda --label "$LABEL" --out "$W/mitsuba/mitsuba.jsonl" \
            ${MITSUBA_ARGS:-} ;;
    embreex)
        mkdir -p "$W/embreex"
        python3 -m pip install -q --no-index --no-deps --no-cache-dir --upgrade --target /tmp/site-emb .emb/*.whl \
            > "$W/embreex/install.log" 2>&1 || echo "embreex: .emb/*.whl did not install (install.log)" | tee -a "$W/steps.log"
        # shellcheck disable=SC2086
        step embreex/embreex "${EMBREEX_S:-300}" env PYTHONPATH="/tmp/site-emb:$PYTHONPATH" python3 benchmarks/peers.py \
            embreex --label "$LABEL" --out "$W/embreex/embreex.jsonl" ${EMBREEX_ARGS:---subdivisions 6 8} ;;
    *) echo "unknown step $s" | tee -a "$W/steps.log" ;;
    esac
done
tar -czf "$OUT/lease.tar.gz" -C "$W" .
cat "$W/steps.log"; [ -f "$W/pytest.log" ] && tail -3 "$W/pytest.log"
