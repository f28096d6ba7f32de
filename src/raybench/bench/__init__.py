"""The thesis's experiments as a benchmark: suites of points, a runner that
times them, JSON Lines results, and a report with plots and verdicts."""
