"""Lab side of seed 002: MTF predictions of the whiskbroom TDI camera (published sinc,
improved) and the slanted-edge measurement, validated against the pixel-level TDI
simulation as a study of the shared runner (:mod:`budget.whiskbroom.study`)."""
