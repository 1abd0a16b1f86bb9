"""The worlds' unmodelled effects (issue 22): the shape shared by every study's scenario.

Minimal version written by the scan-mirror helper to the lead's contract; the lead keeps
helper W3's version of this module.

* :class:`EffectsBase`: every field one effect's magnitude (a float, unit in the name),
  0 = off, default = the sourced realistic magnitude (the source in the field description).
* :class:`WorldBase`: ``effects`` plus the model forms' secondary settings.
"""

from __future__ import annotations

from typing import Self

from simcam.config_base import StrictModel

__all__ = ["EffectsBase", "WorldBase"]


class EffectsBase(StrictModel):
    """Magnitudes of a world's unmodelled effects (0 = off)."""

    def names(self) -> tuple[str, ...]:
        """The effects' names, in field order."""
        return tuple(type(self).model_fields)

    def active(self) -> tuple[str, ...]:
        """The effects that are on (non-zero magnitude)."""
        return tuple(n for n in self.names() if getattr(self, n) != 0)

    def ideal(self) -> Self:
        """Every effect off."""
        return self.model_copy(update={n: 0.0 for n in self.names()})

    def only(self, name: str) -> Self:
        """Every effect off but ``name``, kept at its value."""
        if name not in self.names():
            raise ValueError(f"{name}: not an effect of {type(self).__name__} ({', '.join(self.names())})")
        return self.model_copy(update={n: 0.0 for n in self.names() if n != name})


class WorldBase(StrictModel):
    """A world: its effects' magnitudes and the settings of their model forms (subclassed per instrument)."""

    effects: EffectsBase = EffectsBase()
