"""The world's unmodelled effects: one shape for every study.

A study's simulated world carries effects that the lab's method does not model (a
positioning error with backlash, a detector non-linearity, a tracker bias ...). Each
instrument declares them as a subclass of :class:`EffectsBase`, held by a subclass of
:class:`WorldBase` in its scenario model (``world: <Instrument>World = <Instrument>World()``):

.. code-block:: toml

    [world.effects]        # magnitudes: 0 is off, the default is the sourced realistic value
    hexapod_repeatability_arcsec = 0.5   # hexapod data sheet, bidirectional repeatability
    [world]                # settings of the effects' model forms (time constants, frequencies)
    drift_time_constant_s = 600.0

Rules the classes enforce when a subclass is defined (a :class:`TypeError` then):

* every field of an :class:`EffectsBase` subclass is one effect's **magnitude**: a
  ``float`` with its unit in the name, ``0`` meaning off, its default the sourced realistic
  magnitude, and a ``Field(description=...)`` holding the one-line physical source of that
  default (reports quote it);
* a :class:`WorldBase` subclass's further fields are settings of the model forms, never a
  switch (no ``bool`` field): an effect is off when its magnitude is 0, nowhere else.

Magnitudes must be finite (a NaN or an infinity is a :class:`simcam.infra.errors.ScenarioError`
naming the field, like every scenario value). The lab side never reads ``world``: only the
simulator and the truth routes do. A robustness run (:mod:`budget.runner.robustness`)
builds its cases from :meth:`EffectsBase.ideal` and :meth:`EffectsBase.only` values.
"""

from __future__ import annotations

import math
from typing import Any, Self

from pydantic import field_validator

from simcam.config_base import StrictModel

__all__ = ["EffectsBase", "WorldBase", "scenario_effects"]


class EffectsBase(StrictModel):
    """The magnitudes of a world's unmodelled effects (see the module docstring).

    The base has no effect; an instrument subclasses it with one ``float`` field per effect.
    """

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        for name, info in cls.model_fields.items():
            if info.annotation is not float:
                raise TypeError(f"{cls.__name__}.{name}: an effect is a float magnitude (0 = off), "
                                f"got {info.annotation!r}")
            if not info.description:
                raise TypeError(f"{cls.__name__}.{name}: give Field(description=...) with the physical "
                                "source of its default magnitude")
            if info.default is None or not math.isfinite(float(info.default)):
                raise TypeError(f"{cls.__name__}.{name}: the default magnitude must be a finite float")

    @field_validator("*")
    @classmethod
    def _finite(cls, v: Any) -> Any:
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError("an effect's magnitude must be a finite number (0 = off)")
        return v

    # ------------------------------------------------------------------ queries
    def names(self) -> tuple[str, ...]:
        """Every effect, in field order."""
        return tuple(type(self).model_fields)

    def active(self) -> tuple[str, ...]:
        """The effects that are on (a non-zero magnitude), in field order."""
        return tuple(n for n in self.names() if getattr(self, n) != 0.0)

    def magnitudes(self) -> dict[str, float]:
        """``{name: magnitude}`` in field order."""
        return {n: float(getattr(self, n)) for n in self.names()}

    @classmethod
    def sources(cls) -> dict[str, str]:
        """``{name: the one-line physical source of its default magnitude}``."""
        return {n: info.description or "" for n, info in cls.model_fields.items()}

    # ------------------------------------------------------------------ variants
    def _with(self, values: dict[str, float]) -> Self:
        return type(self).model_validate({**self.magnitudes(), **values})

    def ideal(self) -> Self:
        """Every effect off (all magnitudes 0)."""
        return self._with({n: 0.0 for n in self.names()})

    def only(self, name: str) -> Self:
        """Every effect off but ``name``, kept at its magnitude here."""
        if name not in self.names():
            raise KeyError(f"{type(self).__name__}: no effect {name!r}; effects: {', '.join(self.names()) or 'none'}")
        return self._with({n: 0.0 for n in self.names() if n != name})


class WorldBase(StrictModel):
    """What the simulated world has beyond the lab's model: ``effects`` (magnitudes) and, in
    a subclass, settings of the effects' model forms (unit in the name, never a switch)."""

    effects: EffectsBase = EffectsBase()

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        ann = cls.model_fields["effects"].annotation
        if not (isinstance(ann, type) and issubclass(ann, EffectsBase)):
            raise TypeError(f"{cls.__name__}.effects: must be an EffectsBase subclass, got {ann!r}")
        for name, info in cls.model_fields.items():
            if info.annotation is bool:
                raise TypeError(f"{cls.__name__}.{name}: a world setting never switches an effect on or off "
                                "(an effect is off when its magnitude in [world.effects] is 0)")


def scenario_effects(scenario: Any) -> EffectsBase | None:
    """The scenario's ``world.effects``, or None when its study has no world effects."""
    world = getattr(scenario, "world", None)
    effects = getattr(world, "effects", None)
    return effects if isinstance(effects, EffectsBase) else None
