"""The tests' shorthand for a refinement: the settings given as keywords beside the inputs."""

from __future__ import annotations

from robotcal.identification.refine import RefinementSettings, refine_parameters

#: The keywords that are inputs of :func:`refine_parameters`, not settings.
INPUTS = ("tracker_from_base", "joint_model", "instrument")


def refine(capture, start, targets, **keywords):
    """:func:`refine_parameters` with ``keywords`` split into its inputs and a :class:`RefinementSettings`."""
    inputs = {key: keywords.pop(key) for key in INPUTS if key in keywords}
    return refine_parameters(capture, start, targets, settings=RefinementSettings(**keywords), **inputs)
