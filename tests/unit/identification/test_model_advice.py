"""A MODEL ERROR's advice knows which model was fitted (issue 29, item 5): it names the joint models the fit lacks,
never the one just fitted, and after the fullest model it points at what no joint model holds."""

from __future__ import annotations

import pytest

from robotcal.identification.health import assess_fit, model_advice


@pytest.mark.parametrize(
    ("fitted", "named", "not_named"),
    [
        ("geometric", ["--model compliance", "--model harmonic", "--model auto"], []),
        (None, ["--model compliance", "--model harmonic"], []),
        ("compliance", ["--model harmonic", "--model auto"], ["--model compliance`", "compliance+harmonic"]),
        ("harmonic", ["--model compliance", "--model auto"], ["--model harmonic`", "compliance+harmonic"]),
        ("compliance+harmonic", ["every joint model", "robotcal joints", "repeatability"], ["--model"]),
    ],
)
def test_the_advice_names_only_the_models_not_fitted(fitted, named, not_named):
    advice = model_advice(fitted)
    assert all(text in advice for text in named), advice
    assert not any(text in advice for text in not_named), advice


def test_a_model_error_carries_the_fitted_models_advice():
    health = assess_fit("refinement", residual_sd_mm=0.05, noise_sd_mm=0.005, fitted_model="compliance")
    assert health.verdict == "MODEL ERROR"
    assert health.advice == (model_advice("compliance"),) and "--model compliance`" not in health.advice[0]
