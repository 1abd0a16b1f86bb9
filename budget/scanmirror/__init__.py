"""Lab methods on the GEO scan mirror (seed 003): compensation and normal-deviation estimation."""
