"""Where a mesh's cpu frame spends its time, instruction by instruction: the meshes suite's
icosphere seen from (0, 0, -3), 1680x1050, frames on one thread for SECONDS under `perf record`,
then each sample placed in the machine code that Numba compiled (it names none of it to perf: the
code's pages are copied from /proc/self/mem once the frames are warm, and disassembled with
objdump). Writes DIR/annotated.txt (each instruction with its share of the samples in that code)
and prints the hottest stretches; reading them against the kernel's source is by hand.

    PYTHONPATH=src python benchmarks/archive/jit_profile.py 8 6 /tmp/profile

Needs perf and objdump (binutils). Used for docs/triangles.md's "Where a dense mesh's frame goes".
"""

import collections
import os
import re
import subprocess
import sys
import time


def frames(subdivisions: int, seconds: float, out: str) -> None:
    """The child: warm frames, the compiled code's pages copied, then frames for `seconds`."""
    import raybench
    from raybench import Camera
    from raybench.bench import meshes
    from raybench.mesh_render import mesh_scene

    camera = Camera(position=(0.0, 0.0, -3.0), look_at=(0.0, 0.0, 0.0), fov_deg=60.0)
    with raybench.Renderer(mesh_scene(meshes.icosphere(20 * 4**subdivisions)), 1680, 1050, device="cpu",
                           threads=1) as renderer:  # fmt: skip
        renderer.render(camera)
        with open("/proc/self/maps") as maps, open("/proc/self/mem", "rb") as mem:
            for line in maps:
                parts = line.split()
                if "x" in parts[1] and (len(parts) < 6 or parts[5].startswith("[anon")):
                    start, end = (int(a, 16) for a in parts[0].split("-"))
                    mem.seek(start)
                    with open(os.path.join(out, f"code-{start:x}.bin"), "wb") as f:
                        f.write(mem.read(end - start))
        start = time.perf_counter()
        while time.perf_counter() - start < seconds:
            renderer.render(camera)


def main(subdivisions: int, seconds: float, out: str) -> None:
    os.makedirs(out, exist_ok=True)
    data = os.path.join(out, "perf.data")
    subprocess.run(["perf", "record", "-F", "4000", "-o", data, sys.executable, __file__, "--child",
                    str(subdivisions), str(seconds), out], check=True, capture_output=True)  # fmt: skip
    script = subprocess.run(["perf", "script", "-i", data, "-F", "ip"], check=True, capture_output=True, text=True)
    samples = collections.Counter(int(line, 16) for line in script.stdout.split())
    regions = []
    for name in os.listdir(out):
        if name.startswith("code-"):
            start = int(name[5:-4], 16)
            regions.append((start, start + os.path.getsize(os.path.join(out, name)), name))
    inside = collections.Counter()
    for ip, n in samples.items():
        for start, end, name in regions:
            if start <= ip < end:
                inside[name] += n
    name, _ = inside.most_common(1)[0]  # the frame's program: most of the samples
    start = int(name[5:-4], 16)
    listing = subprocess.run(["objdump", "-D", "-b", "binary", "-m", "i386:x86-64", "-M", "intel",
                              f"--adjust-vma={start}", os.path.join(out, name)], check=True, capture_output=True,
                             text=True).stdout  # fmt: skip
    total = sum(n for ip, n in samples.items() if start <= ip < start + os.path.getsize(os.path.join(out, name)))
    lines = []
    for line in listing.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(?:[0-9a-f]{2} )+\s*(.*)", line)
        if m:
            lines.append((100.0 * samples.get(int(m.group(1), 16), 0) / total, int(m.group(1), 16) - start, m.group(2)))
    with open(os.path.join(out, "annotated.txt"), "w") as f:
        for share, offset, text in lines:
            f.write(f"{share:6.2f} {offset:6x} {text}\n")
    print(f"{total} samples in the program ({100.0 * total / sum(samples.values()):.0f}% of all)")
    window, shares = 50, [share for share, _, _ in lines]
    best = sorted(((sum(shares[i : i + window]), i) for i in range(0, len(shares), 10)), reverse=True)
    taken: list[int] = []
    for share, i in best:
        if all(abs(i - j) >= window for j in taken):
            taken.append(i)
            print(f"{share:5.1f}%  from offset {lines[i][1]:x}")
        if len(taken) == 10:
            break


if __name__ == "__main__":
    if sys.argv[1] == "--child":
        frames(int(sys.argv[2]), float(sys.argv[3]), sys.argv[4])
    else:
        main(int(sys.argv[1]), float(sys.argv[2]), sys.argv[3])
