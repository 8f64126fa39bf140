"""Instrument presets (``robotcal/data/instruments.toml``) and instrument tables of scenarios."""

from __future__ import annotations

from robotcal.errors import InputError
from robotcal.instruments import Instrument
from robotcal.io._validation import as_finite_float
from robotcal.io.builtins import data_path, read_toml

__all__ = ["instrument_presets", "make_instrument"]


def instrument_presets() -> dict[str, dict]:
    """Presets by name: ``{"a_um", "b_um_per_m", "description"}``."""
    return read_toml(data_path("instruments.toml"))


def make_instrument(
    *,
    preset: str | None = None,
    a_um: float | None = None,
    b_um_per_m: float | None = None,
    noise: str = "uniform",
    coverage_factor: float = 2.0,
) -> Instrument:
    """Instrument from a preset and/or explicit terms (explicit values override the preset's).

    The terms are numbers: a boolean (``true`` in a TOML file) or a text is an :class:`InputError` naming the key,
    never read as 1 or 0.
    """
    name, description = "custom", ""
    if preset is not None:
        presets = instrument_presets()
        if preset not in presets:
            raise InputError(f"unknown instrument preset {preset!r}; known presets: {', '.join(sorted(presets))}")
        entry = presets[preset]
        name, description = preset, entry.get("description", "")
        a_um = entry["a_um"] if a_um is None else a_um
        b_um_per_m = entry["b_um_per_m"] if b_um_per_m is None else b_um_per_m
    if a_um is None or b_um_per_m is None:
        raise InputError("an instrument needs a `preset` or both `a_um` and `b_um_per_m`")
    where = f"instrument {name!r}: key " if preset is not None else "instrument: key "
    return Instrument(
        name=name,
        a_mm=as_finite_float(a_um, f"{where}`a_um`") / 1000.0,
        b_mm_per_m=as_finite_float(b_um_per_m, f"{where}`b_um_per_m`") / 1000.0,
        noise=noise,
        coverage_factor=as_finite_float(coverage_factor, f"{where}`coverage_factor`"),
        description=description,
    )
