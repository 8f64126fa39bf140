"""ISO 9283 results as CSV (``robotcal iso9283``, the run's ``iso9283/`` folder; docs/iso9283.md).

Columns ``model,pose,APx,APy,APz,AP,l_bar,S_l,RP,AD,RD`` [mm] and ``APa,APb,APc,RPa,RPb,RPc`` [deg]
(empty without orientation); one row per model and test pose, and one row ``Pa-Pb`` per model with the
distance characteristics AD, RD.
"""

from __future__ import annotations

import numpy as np

__all__ = ["ISO_COLUMNS", "iso_to_csv"]

ISO_COLUMNS = (
    "model", "pose", "APx", "APy", "APz", "AP", "l_bar", "S_l", "RP", "AD", "RD",
    "APa", "APb", "APc", "RPa", "RPb", "RPc",
)  # fmt: skip


def iso_to_csv(results: dict) -> str:
    """The CSV text of ``{model: Iso9283Result}``: positions [mm], distances [mm], orientation [deg]."""
    lines = [",".join(ISO_COLUMNS)]
    for label, r in results.items():
        for k in range(r.ap.shape[0]):
            values = [*r.ap_xyz[k], r.ap[k], r.l_bar[k], r.s_l[k], r.rp[k]]
            if r.has_orientation:
                angles = ",".join(f"{v:.6f}" for v in np.rad2deg(np.r_[r.ap_abc[k], r.rp_abc[k]]))
            else:
                angles = "," * 5
            lines.append(f"{label},P{k + 1}," + ",".join(f"{v:.6f}" for v in values) + ",,," + angles)
        a, b = r.distance_pair
        lines.append(f"{label},P{a + 1}-P{b + 1}" + "," * 8 + f"{r.ad:.6f},{r.rd:.6f}" + "," * 6)
    return "\n".join(lines) + "\n"
