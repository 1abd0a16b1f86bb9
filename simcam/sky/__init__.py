"""The sky shared by the instruments that look at stars: the Hipparcos catalogue and
apparent places (proper motion, parallax, aberration) computed through astropy."""
