"""Mark all but a seeded sample of each session's pending mutants as skipped
("not sampled"). Kernels: half the quota from comparison, number, boolean
and keyword operators, half from the rest; other modules: uniform."""

import random
import re
import sqlite3

SEED = 18
QUOTA = {
    "kernels_intersect": 30,
    "kernels_shade": 10,
    "kernels_trace": 20,
    "kernels_traverse": 20,
    "kernels_whitted": 15,
    "backends_cpu": 25,
    "backends_cuda": 12,
    "backends_cuda_build": 12,
    "backends_limits": 18,
    "backends_contract": 10,
    "backends_walks": 99,
    "scene": 30,
}
PRIORITY = re.compile(
    r"ReplaceComparisonOperator|NumberReplacer|ReplaceAndWithOr|ReplaceOrWithAnd|AddNot|ReplaceTrueWithFalse"
    r"|ReplaceFalseWithTrue|ReplaceBreakWithContinue|ReplaceContinueWithBreak"
)
for name, quota in QUOTA.items():
    rng = random.Random(f"{SEED}-{name}")
    db = sqlite3.connect(f"/tmp/cr/{name}.sqlite")
    rows = db.execute(
        "select job_id, operator_name from mutation_specs"
        " where job_id not in (select job_id from work_results) order by job_id"
    ).fetchall()
    if name.startswith("kernels"):
        pri = [j for j, op in rows if PRIORITY.search(op)]
        rest = [j for j, op in rows if not PRIORITY.search(op)]
        a = min(len(pri), quota // 2 + quota % 2)
        chosen = rng.sample(pri, a) + rng.sample(rest, min(len(rest), quota - a))
    else:
        chosen = rng.sample([j for j, _ in rows], min(len(rows), quota))
    keep = set(chosen)
    for j, _ in rows:
        if j not in keep:
            db.execute(
                "insert into work_results (worker_outcome, output, test_outcome, diff, job_id)"
                " values ('SKIPPED', 'not sampled', NULL, NULL, ?)",
                (j,),
            )
    db.commit()
    print(name, "pending", len(rows), "sampled", len(keep))
