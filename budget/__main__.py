"""``python -m budget``: the ``budget`` command."""

from simcam.lifecycle import budget_entry

budget_entry()
