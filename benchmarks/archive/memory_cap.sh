#!/usr/bin/env bash
# memory_cap.sh GIB LOG COMMAND...: COMMAND run inside a memory cgroup capped at GIB GiB (a
# machine of that memory, as far as the command can tell: past the cap it is reclaimed from,
# then killed), timed by GNU time; LOG gets its output, its exit status, GNU time's report
# (peak resident set among it) and the cgroup's peak usage and how often the cap was hit.
# Needs root and the cgroup memory controller (v2: memory.max and memory.peak; or v1).
# Issue 38's "renders on a 16 GiB CPU machine":
#   raybench scene spd balls --size 6 -o balls6.nff
#   bash benchmarks/archive/memory_cap.sh 16 balls6.log raybench render balls6.nff --device cpu \
#       --size 1680x1050 --shading whitted -o balls6.png
set -uo pipefail
if [ $# -lt 3 ]; then echo "usage: memory_cap.sh GIB LOG COMMAND..." >&2; exit 2; fi
gib=$1 log=$2; shift 2
case $gib in ''|*[!0-9]*) echo "memory_cap.sh: GIB must be a whole number of GiB, got '$gib'" >&2; exit 2 ;; esac
bytes=$((gib * 1024 * 1024 * 1024))
if [ -f /sys/fs/cgroup/cgroup.controllers ]; then  # v2
    group=/sys/fs/cgroup/raybench-cap-$$
    mkdir "$group" && echo "$bytes" > "$group/memory.max" && echo 0 > "$group/memory.swap.max" 2>/dev/null
    peak=memory.peak failed=memory.events
else  # v1
    group=/sys/fs/cgroup/memory/raybench-cap-$$
    mkdir "$group" && echo "$bytes" > "$group/memory.limit_in_bytes"
    peak=memory.max_usage_in_bytes failed=memory.failcnt
fi || { echo "memory_cap.sh: cannot make a memory cgroup (root and the memory controller are needed)" >&2; exit 2; }
trap 'rmdir "$group" 2>/dev/null' EXIT
# the command's own shell joins the group; its children are born in it
bash -c 'echo $$ > "$1/cgroup.procs" && shift && exec /usr/bin/time -v "$@"' _ "$group" "$@" > "$log" 2>&1
status=$?
{ echo "exit status: $status"; echo "cap: $gib GiB"; echo "cgroup peak bytes: $(cat "$group/$peak")"
  echo "cap hit ($failed): $(tr '\n' ' ' < "$group/$failed")"; } >> "$log"
tail -4 "$log"
exit $status
