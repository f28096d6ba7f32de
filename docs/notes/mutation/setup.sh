#!/bin/bash
# The sessions of the run in docs/notes/mutation.md: a copy of the tree outside any
# git worktree (/tmp/mut-tree), one cosmic-ray session per module (/tmp/cr),
# the operators that cannot apply filtered out, then the seeded sample
# (sample.py). Then drive.sh runs them, one mutant at a time.
set -e
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p /tmp/mut-tree /tmp/cr/sel
git -C "$here/../../.." archive HEAD | tar -x -C /tmp/mut-tree
cp "$here"/*.txt /tmp/cr/sel/ && cp "$here"/runsel.sh /tmp/cr/
for m in kernels/intersect kernels/shade kernels/trace kernels/traverse kernels/whitted backends/cpu backends/cuda \
         backends/cuda_build backends/limits backends/contract backends/walks scene; do
  n=$(echo $m | tr / _)
  case $n in kernels_*|backends_cpu) s=kern;; backends_cuda) s=cuda;; backends_cuda_build) s=build;; scene) s=scene;; *) s=limits;; esac
  printf '#!/bin/bash\nexec /tmp/cr/runsel.sh %s\n' $s > /tmp/cr/run_$n.sh && chmod +x /tmp/cr/run_$n.sh
  sed "s#kernels/intersect#$m#; s#kernels_intersect#$n#" "$here/cr-example.toml" > /tmp/cr/$n.toml
  (cd /tmp/mut-tree && cosmic-ray init /tmp/cr/$n.toml /tmp/cr/$n.sqlite && cr-filter-operators /tmp/cr/$n.sqlite /tmp/cr/$n.toml)
done
python3 "$here/sample.py"
