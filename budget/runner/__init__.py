"""Shared Monte Carlo machinery: the study contract, the runner, statistics, results.

See :mod:`budget.runner.study` for what a study provides and :mod:`budget.runner.run`
for what the runner does with it.
"""
