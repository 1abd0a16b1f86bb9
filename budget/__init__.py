"""budget: the lab. Turns measurements into error estimates (and, in validation, compares them to truth)."""

__version__ = "0.1.0"
