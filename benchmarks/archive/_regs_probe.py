import sys, raybench
from raybench.backends.cuda import program as P
s = raybench.random_spheres(10000, seed=1)
r = raybench.render(s, raybench.Camera(), 1680, 1050, device="cuda", walk="packet")
for name in ("_bvh_packet_kernel", "_bvh_kernel"):
    k = getattr(P, name)
    for sig, o in k.overloads.items():
        print(sys.argv[1], name, "regs", o.get_regs_per_thread(), "local", o.get_local_mem_per_thread(), "shared", o.get_shared_mem_per_block())
