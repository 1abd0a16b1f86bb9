"""budget: the lab. Turns measurements into error estimates (and, in validation, compares them to truth).

The Python API (docs/api.md): :func:`budget.validate`, :func:`budget.claims`, :func:`budget.robustness`, :func:`budget.plan`,
:func:`budget.sweep`, :func:`budget.studies`, :func:`budget.scenario_text` (:mod:`budget.api`).
They are looked up on first use, so ``import budget`` (and the console script's start,
:mod:`budget.__main__`) imports nothing else.
"""

__version__ = "0.1.0"

__all__ = ["claims", "plan", "robustness", "scenario_text", "studies", "sweep", "validate"]


def __getattr__(name: str):
    """The Python API's functions, imported from :mod:`budget.api` when first asked for (PEP 562)."""
    if name in __all__:
        from budget import api

        return getattr(api, name)
    raise AttributeError(f"module 'budget' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
