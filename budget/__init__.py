"""budget: the lab. Turns measurements into error estimates (and, in validation, compares them to truth).

The Python API (docs/api.md): :func:`budget.validate`, :func:`budget.robustness`, :func:`budget.plan`, :func:`budget.sweep`, :func:`budget.studies`, :func:`budget.scenario_text`.
"""

__version__ = "0.1.0"

from budget.api import plan, robustness, scenario_text, studies, sweep, validate  # noqa: E402  (light: imports nothing heavy)

__all__ = ["plan", "robustness", "scenario_text", "studies", "sweep", "validate"]
