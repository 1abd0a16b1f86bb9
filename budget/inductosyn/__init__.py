"""Seed 001: polygon calibration of a round inductosyn's harmonic errors, as a study."""
