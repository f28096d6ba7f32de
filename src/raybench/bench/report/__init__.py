"""The report: results files in, one Markdown file with PNG charts out, and a
verdict on each of the thesis's claims for every machine measured.

One module a job, each reading only those before it:
  numbers   numbers as text, for the modules below
  records   results files read and checked; records grouped by machine and
            kernel (column()), files with the same label merged
  series    the series (speedups, thesis_series, test7_series, cpu_tuning,
            gpu_tuning, constant_vs_runtime, scaling_series, secondary_points,
            secondary_leads, multi_gpu_series, dynamic_points): pure functions of plain
            lists of records, so the rules can be tested on synthetic data
  verdicts  the six claims judged; the thresholds are its constants, RULES
            states them in words, and the report prints it; beyond them,
            SECONDARY_QUESTION judged under SECONDARY_RULE
  charts    the PNG charts (matplotlib, Agg canvas, no pyplot)
  markdown_blocks  what report.md is written with; text from a results file
            enters it only through escape()
  thesis_sections, beyond_sections  report.md's sections: a machine's
            thesis tests, and the suites beyond the thesis
  markdown  report.md laid out, from those sections
"""

from .markdown import write_report
from .markdown_blocks import escape
from .records import _check as _check  # one record at a time, for the tests
from .records import accel_of, column, group, kernel_of, load
from .series import (
    DEVICE_NAMES,
    constant_vs_runtime,
    cpu_tuning,
    dynamic_points,
    gpu_tuning,
    multi_gpu_series,
    scaling_series,
    secondary_leads,
    secondary_points,
    shading_of,
    speedups,
    test7_series,
    theoretical_ratio,
    thesis_series,
)
from .verdicts import (
    CLAIMS,
    FAILS,
    HOLDS,
    NEAR_FASTEST,
    NOT_MEASURED,
    R2_MIN,
    RATIO_BAND,
    RULES,
    RUNTIME_SLOWER,
    SECONDARY_KEPT_MIN,
    SECONDARY_QUESTION,
    SECONDARY_RULE,
    THESIS_CPU,
    THESIS_GPU,
    THESIS_RATIO,
    THESIS_SPEEDUP,
    secondary_verdict,
    verdicts,
)

__all__ = [
    "CLAIMS",
    "DEVICE_NAMES",
    "FAILS",
    "HOLDS",
    "NEAR_FASTEST",
    "NOT_MEASURED",
    "R2_MIN",
    "RATIO_BAND",
    "RULES",
    "RUNTIME_SLOWER",
    "SECONDARY_KEPT_MIN",
    "SECONDARY_QUESTION",
    "SECONDARY_RULE",
    "THESIS_CPU",
    "THESIS_GPU",
    "THESIS_RATIO",
    "THESIS_SPEEDUP",
    "accel_of",
    "column",
    "constant_vs_runtime",
    "cpu_tuning",
    "dynamic_points",
    "escape",
    "gpu_tuning",
    "group",
    "kernel_of",
    "load",
    "multi_gpu_series",
    "scaling_series",
    "secondary_leads",
    "secondary_points",
    "secondary_verdict",
    "shading_of",
    "speedups",
    "test7_series",
    "theoretical_ratio",
    "thesis_series",
    "verdicts",
    "write_report",
]
