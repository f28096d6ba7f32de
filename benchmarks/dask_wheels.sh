#!/usr/bin/env bash
# The wheels the GPU machine needs for raybench.cluster, into .whl/, which
# gpu_lease.sh installs before its steps (the machine has no internet). Its
# Python is 3.12 on x86_64. The issue's probe carried dask, distributed,
# tornado, tblib, zict, partd and locket; the rest of their dependencies
# are carried too, so that nothing depends on what the machine happens to
# have (each is small). Dask and distributed at the versions tested
# (distributed pins its dask exactly):
#   bash benchmarks/dask_wheels.sh && ls .whl
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p .whl
python3 -m pip download -q --only-binary=:all: --no-deps --python-version 3.12 \
    --platform manylinux2014_x86_64 --platform manylinux_2_17_x86_64 --platform manylinux_2_28_x86_64 \
    --implementation cp -d .whl \
    'dask==2026.8.0' 'distributed==2026.8.0' 'tornado>=6.2' 'tblib>=1.6,!=3.2.0,!=3.2.1' 'zict>=3' \
    'partd>=1.4' 'locket>=1' 'cloudpickle>=3' 'toolz>=0.12' 'msgpack>=1.0.2' 'sortedcontainers>=2.0.5' \
    'pyyaml>=5.4.1' 'fsspec>=2021.9' 'jinja2>=2.10.3' 'markupsafe>=2' 'click>=8.1' 'psutil>=5.9' 'packaging>=20' \
    'xxhash>=4.1,<5'
ls .whl | grep -iE 'dask|distributed|tornado|tblib|zict|partd|locket|cloudpickle|toolz|msgpack|yaml|fsspec|jinja|xxhash'
