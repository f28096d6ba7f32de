import sqlite3

order = [
    "kernels_intersect",
    "kernels_shade",
    "kernels_trace",
    "kernels_traverse",
    "kernels_whitted",
    "backends_cpu",
    "backends_cuda",
    "backends_cuda_build",
    "backends_limits",
    "backends_contract",
    "backends_walks",
    "scene",
]
tot = [0] * 6
print("| Module | Mutants | Filtered out | Left | Run (sampled) | Killed | Survived |")
print("|---|---|---|---|---|---|---|")
for n in order:
    db = sqlite3.connect(f"/tmp/cr/{n}.sqlite")

    def q(sql, db=db):
        return db.execute(sql).fetchone()[0]

    total = q("select count(*) from mutation_specs")
    filt = q("select count(*) from work_results where output = 'Filtered operator'")
    run = q("select count(*) from work_results where output is not 'not sampled' and output is not 'Filtered operator'")
    killed = q("select count(*) from work_results where test_outcome = 'KILLED'")
    surv = q("select count(*) from work_results where test_outcome = 'SURVIVED'")
    other = q("select count(*) from work_results where worker_outcome not in ('NORMAL', 'SKIPPED')")
    row = [total, filt, total - filt, run, killed, surv]
    tot = [a + b for a, b in zip(tot, row)]
    path = n.replace("kernels_", "kernels/").replace("backends_", "backends/") + ".py"
    print(f"| `{path}` | " + " | ".join(map(str, row)) + " |" + (f" ({other} abnormal)" if other else ""))
print("| all | " + " | ".join(map(str, tot)) + " |")
