"""The whiskbroom TDICCD space camera of seed 002: image-motion geometry, Monte Carlo
synthesis of the image-motion residual, and a pixel-level TDI simulation."""
