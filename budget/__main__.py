"""``python -m budget`` and the console script ``budget``: the lab's command line."""

from simcam.infra.lifecycle import guarded_entry


def main() -> None:
    """Console script ``budget`` (:func:`simcam.infra.lifecycle.guarded_entry` of :mod:`budget.cli`)."""
    guarded_entry("budget.cli")


if __name__ == "__main__":
    main()
