"""``python -m simcam`` and the console script ``simcam``: the world's command line."""

from simcam.infra.lifecycle import guarded_entry


def main() -> None:
    """Console script ``simcam`` (:func:`simcam.infra.lifecycle.guarded_entry` of :mod:`simcam.cli`)."""
    guarded_entry("simcam.cli")


if __name__ == "__main__":
    main()
