"""simcam: the world. Turns a scenario into pixels and knows the truth it injected."""

__version__ = "0.1.0"
