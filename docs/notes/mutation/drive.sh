#!/bin/bash
# Every session of the run in docs/notes/mutation.md in turn, one mutant at a time (touch /tmp/cr/STOP to stop before the next module).
cd /tmp/mut-tree || exit 1
find . -name __pycache__ -prune -exec rm -rf {} +
for n in kernels_intersect kernels_trace kernels_shade kernels_traverse backends_cpu scene backends_limits backends_walks backends_contract kernels_whitted backends_cuda backends_cuda_build; do
  [ -e /tmp/cr/STOP ] && { echo "stopped before $n"; break; }
  echo "$(date -u +%T) start $n"
  nice -n 15 /tmp/crvenv/bin/cosmic-ray exec /tmp/cr/$n.toml /tmp/cr/$n.sqlite
  echo "$(date -u +%T) end $n rc=$?"
done
echo "$(date -u +%T) all done"
