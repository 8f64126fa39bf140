"""The built-in scenarios, robots and instrument presets as loaded, in a canonical exact form (for a regression test).

``canonical`` turns a loaded object into nested lists of text: every float as ``float.hex`` (bit-exact), every
value with its type name, dataclasses and pydantic models field by field, dict keys in order. Run this file once
(``python tests/unit/io/builtin_reference.py``) to write ``data/builtins_reference.json``; the test
``test_builtins_unchanged`` compares what the loaders give today with it.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

REFERENCE = Path(__file__).parent / "data" / "builtins_reference.json"


def canonical(value):
    """``value`` as nested lists/strings that compare equal exactly when the objects are equal, types included."""
    from pydantic import BaseModel

    kind = type(value).__name__
    if value is None or isinstance(value, bool | str):
        return f"{kind}:{value!r}"
    if isinstance(value, int | np.integer):
        return f"{kind}:{int(value)}"
    if isinstance(value, float | np.floating):
        return f"{kind}:{float(value).hex()}"
    if isinstance(value, np.ndarray):
        return [f"ndarray:{value.dtype}:{value.shape}", [canonical(v) for v in value.ravel().tolist()]]
    if isinstance(value, list | tuple):
        return [kind, [canonical(v) for v in value]]
    if isinstance(value, dict):
        return [kind, [[canonical(k), canonical(v)] for k, v in value.items()]]
    if isinstance(value, BaseModel):
        return [kind, [[name, canonical(getattr(value, name))] for name in type(value).model_fields]]
    if dataclasses.is_dataclass(value):
        return [kind, [[f.name, canonical(getattr(value, f.name))] for f in dataclasses.fields(value)]]
    return f"{kind}:{value!r}"


def loaded_builtins() -> dict:
    """Every built-in scenario, robot and instrument preset, loaded as the product loads them, in canonical form."""
    from robotcal.io.schema.builtins import builtin_names
    from robotcal.io.schema.instruments import instrument_presets, make_instrument
    from robotcal.io.schema.robots import load_robot
    from robotcal.io.schema.scenario import load_scenario

    presets = instrument_presets()
    out = {
        "scenarios": {name: canonical(load_scenario(name)) for name in builtin_names("scenarios")},
        "robots": {name: canonical(load_robot(name)) for name in builtin_names("robots")},
        "presets": canonical(presets),
        "instruments": {
            f"{name}/{noise}": canonical(make_instrument(preset=name, noise=noise))
            for name in presets
            for noise in ("uniform", "normal")
        },
    }
    # the data folder holds absolute paths: keep them relative to it
    data = str(Path(__import__("robotcal").__file__).parent / "data")
    return json.loads(json.dumps(out).replace(data, "<data>"))


if __name__ == "__main__":
    REFERENCE.write_text(json.dumps(loaded_builtins(), indent=0, sort_keys=False) + "\n")
    print(f"wrote {REFERENCE}", file=sys.stderr)
