"""``python -m simcam``: the ``simcam`` command."""

if __name__ == "__main__":
    from simcam.lifecycle import simcam_entry

    simcam_entry()
