"""Seed 000: the laboratory accuracy methods of a star camera (TE, HSFE, LSFE-S, LSFE-C1/C2) as a study."""
