"""``python -m simcam``: the ``simcam`` command."""

from simcam.lifecycle import simcam_entry

simcam_entry()
