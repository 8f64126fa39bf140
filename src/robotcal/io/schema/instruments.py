"""Instrument presets (``robotcal/data/instruments.toml``) and instrument tables of scenarios.

Both are validated by schema: :class:`InstrumentPreset` for an entry of the presets file, :class:`InstrumentTable`
for a scenario's ``[instrument]`` and for the terms given to :func:`make_instrument`.
"""

from __future__ import annotations

from functools import cache
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, RootModel, field_validator, model_validator

from robotcal.instruments import Instrument
from robotcal.io.schema._validation import TomlFloat, validate_model
from robotcal.io.schema.builtins import data_path, read_toml

__all__ = ["InstrumentPreset", "InstrumentTable", "instrument_presets", "make_instrument"]


class InstrumentPreset(BaseModel):
    """One preset: U(L) = A + B*L [um, um/m], and the optional planning figures (``robotcal plan check``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    a_um: TomlFloat = Field(ge=0)
    b_um_per_m: TomlFloat = Field(ge=0)
    description: str = ""
    min_distance_m: TomlFloat | None = Field(default=None, ge=0)
    max_distance_m: TomlFloat | None = Field(default=None, gt=0)
    reflector_acceptance_deg: TomlFloat | None = Field(default=None, gt=0, le=180)
    orientation_deg: TomlFloat | None = Field(default=None, ge=0)  # a 6-DoF probe's orientation U [deg]

    @model_validator(mode="after")
    def _range(self) -> InstrumentPreset:
        low, high = self.min_distance_m, self.max_distance_m
        if low is not None and high is not None and low >= high:
            raise ValueError("min_distance_m must be below max_distance_m")
        return self


class _Presets(RootModel[dict[str, InstrumentPreset]]):
    pass


@cache
def _validated_presets() -> dict[str, dict]:
    path = data_path("instruments.toml")
    presets: _Presets = validate_model(_Presets, read_toml(path), str(path))
    return {name: entry.model_dump(exclude_unset=True) for name, entry in presets.root.items()}


def instrument_presets() -> dict[str, dict]:
    """Presets by name: ``{"a_um", "b_um_per_m", "description"}`` and the planning keys the file gives."""
    return {name: dict(entry) for name, entry in _validated_presets().items()}


class InstrumentTable(BaseModel):
    """A scenario's ``[instrument]``: a ``preset`` and/or explicit terms (explicit values override the preset's)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    preset: str | None = None
    a_um: TomlFloat | None = Field(default=None, ge=0)
    b_um_per_m: TomlFloat | None = Field(default=None, ge=0)
    noise: Literal["uniform", "normal"] = "uniform"
    coverage_factor: TomlFloat = Field(default=2.0, gt=0)
    orientation_deg: TomlFloat | None = Field(default=None, ge=0)  # a 6-DoF probe's orientation U [deg]

    @field_validator("preset")
    @classmethod
    def _known(cls, preset: str | None) -> str | None:
        presets = _validated_presets()
        if preset is not None and preset not in presets:
            raise ValueError(f"unknown instrument preset {preset!r}; known presets: {', '.join(sorted(presets))}")
        return preset

    @model_validator(mode="after")
    def _complete(self) -> InstrumentTable:
        if self.preset is None and (self.a_um is None or self.b_um_per_m is None):
            raise ValueError("an instrument needs a `preset` or both `a_um` and `b_um_per_m`")
        return self


def make_instrument(
    *,
    preset: str | None = None,
    a_um: float | None = None,
    b_um_per_m: float | None = None,
    noise: str = "uniform",
    coverage_factor: float = 2.0,
    orientation_deg: float | None = None,
) -> Instrument:
    """Instrument from a preset and/or explicit terms (explicit values override the preset's).

    The terms are validated by :class:`InstrumentTable`: a boolean (``true`` in a TOML file) or a text is an
    :class:`InputError` naming the key, never read as 1 or 0.
    """
    terms = {"preset": preset, "a_um": a_um, "b_um_per_m": b_um_per_m, "noise": noise, "orientation_deg": orientation_deg}
    source = "instrument" if preset is None else f"instrument {preset!r}"
    table: InstrumentTable = validate_model(InstrumentTable, terms | {"coverage_factor": coverage_factor}, source)
    name, description, a_um, b_um_per_m = "custom", "", table.a_um, table.b_um_per_m
    if table.preset is not None:
        entry = _validated_presets()[table.preset]
        name, description = table.preset, entry.get("description", "")
        a_um = entry["a_um"] if a_um is None else a_um
        b_um_per_m = entry["b_um_per_m"] if b_um_per_m is None else b_um_per_m
        orientation_deg = entry.get("orientation_deg") if orientation_deg is None else orientation_deg
    assert a_um is not None and b_um_per_m is not None  # InstrumentTable: a preset or both terms
    return Instrument(
        name=name,
        a_mm=a_um / 1000.0,
        b_mm_per_m=b_um_per_m / 1000.0,
        noise=table.noise,
        coverage_factor=table.coverage_factor,
        description=description,
        orientation_rad=None if orientation_deg is None else float(np.deg2rad(orientation_deg)),
    )
