"""GEO two-axis scan mirror (seed 003): geometry, orbit, attitude, scan plan, star sensing."""
