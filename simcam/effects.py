"""Unmodelled effects of a world (issue 22): the shape every instrument's ``[world]`` table shares.

Minimal version written by the line-camera helper to the lead's contract
(``EffectsBase``/``WorldBase``); the lead keeps the robustness helper's version at merge.

* :class:`EffectsBase`: every field is one unmodelled effect's MAGNITUDE, a float with its
  unit in the name, ``0`` meaning off, default = the sourced realistic magnitude (the
  field's description holds the one-line physical source).
* :class:`WorldBase`: ``effects`` plus optional settings of the effects' model forms
  (time constants, frequencies), which never switch anything on or off.
"""

from __future__ import annotations

from simcam.config_base import StrictModel

__all__ = ["EffectsBase", "WorldBase"]


class EffectsBase(StrictModel):
    """Magnitudes of a world's unmodelled effects (0 = off)."""

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The effects, in field order."""
        return tuple(cls.model_fields)

    def active(self) -> tuple[str, ...]:
        """The effects that are on (non-zero magnitude)."""
        return tuple(n for n in self.names() if getattr(self, n) != 0)

    def ideal(self):
        """Every effect off."""
        return self.model_copy(update={n: 0.0 for n in self.names()})

    def only(self, name: str):
        """Every effect off except ``name`` (kept at its value)."""
        if name not in self.names():
            raise ValueError(f"{name}: not an effect of {type(self).__name__} ({', '.join(self.names())})")
        return self.model_copy(update={n: 0.0 for n in self.names() if n != name})


class WorldBase(StrictModel):
    """A world: its effects' magnitudes and the settings of their model forms."""

    effects: EffectsBase = EffectsBase()
