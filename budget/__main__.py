"""``python -m budget``: the ``budget`` command."""

if __name__ == "__main__":
    from simcam.lifecycle import budget_entry

    budget_entry()
