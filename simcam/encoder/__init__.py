"""The round inductosyn angle encoder of seed 001 and its polygon calibration rig."""
