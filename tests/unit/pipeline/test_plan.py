"""plan_run checks everything before any computation and writes nothing; run_calibration needs a folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from robotcal.errors import InputError
from robotcal.io.schema.scenario import load_scenario
from robotcal.pipeline import RunPlan, plan_run, run_calibration
from robotcal.pipeline.plan import REFINED_DRAWS, SEED_OFFSETS


def test_plan_without_a_folder_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    plan = plan_run("kr5-demo")
    assert isinstance(plan, RunPlan) and plan.out is None
    assert list(tmp_path.iterdir()) == []
    # the scenario's seeds, its Monte Carlo size, and its refined Monte Carlo size (montecarlo.refined_iterations)
    assert plan.seeds == {
        "capture": 1, "truth": 11, "validation": 2, "montecarlo": 1, "workspace": 0, "iso9283": 6, "poses": 3
    }  # fmt: skip
    assert plan.montecarlo.iterations == 100_000 and plan.refined_montecarlo.iterations == 100_000
    assert plan.backlash and plan.command == "robotcal run"
    with pytest.raises(InputError, match="needs a run folder"):
        run_calibration(plan)
    assert list(tmp_path.iterdir()) == []


def test_one_seed_seeds_every_part(tmp_path):
    plan = plan_run("kr5-demo", tmp_path / "out", seed=40, draws=500, workspace=7)
    assert plan.seeds == {name: 40 + offset for name, offset in SEED_OFFSETS.items()}
    assert plan.refined_montecarlo.iterations == 500  # at most the CPA Monte Carlo's draws
    assert plan.tcp.workspace_poses == 7
    assert not (tmp_path / "out").exists()


def test_refined_draws_come_from_the_option_then_the_scenario_then_the_default(tmp_path):
    demo = Path(load_scenario("kr5-demo").source)
    text = demo.read_text(encoding="utf-8")
    assert "\nrefined_iterations = 100000\n" in text
    without = tmp_path / "demo-without.toml"
    without.write_text(text.replace("\nrefined_iterations = 100000\n", "\n"), encoding="utf-8")
    assert plan_run(without).refined_montecarlo.iterations == REFINED_DRAWS
    assert plan_run("kr5-demo", refined_draws=700).refined_montecarlo.iterations == 700
    assert plan_run("kr5-demo", draws=3000).refined_montecarlo.iterations == 3000  # capped by the draws
    # too few for a 95 % interval: the error names the scenario's key, not an option the user did not give
    few = tmp_path / "demo-few.toml"
    few.write_text(text.replace("\nrefined_iterations = 100000\n", "\nrefined_iterations = 5\n"), encoding="utf-8")
    with pytest.raises(InputError, match=r"demo-few\.toml: montecarlo\.refined_iterations: `iterations` = 5 is too few"):
        plan_run(few)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"draws": 10}, "iterations"),
        ({"draws": 1000, "refined_draws": 1001}, r"--refined-draws must be between 1 and the Monte Carlo draws \(1,000\)"),
        ({"workspace": 0}, "--workspace must be a positive number"),
        ({"seed": 2**63 - 2}, r"seed .* is outside \[0, 2\^63\)"),
    ],
)
def test_bad_options_are_refused_before_work(tmp_path, options, message):
    with pytest.raises(InputError, match=message):
        plan_run("kr5-demo", tmp_path / "out", **options)
    assert not (tmp_path / "out").exists()


def test_a_folder_robotcal_did_not_write_is_refused(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("mine", encoding="utf-8")
    (out / "cpa").mkdir()
    with pytest.raises(InputError, match="--force"):
        plan_run("kr5-demo", out)
    assert plan_run("kr5-demo", out, force=True).force


def test_a_scenario_without_a_capture_plan_is_refused_naming_the_plan_first(tmp_path):
    # only unknown flange targets: no validation target either, but the missing plan is the first thing to say
    scenario = tmp_path / "cell.toml"
    scenario.write_text(
        'robot = "abb-irb120"\n[[targets]]\nname = "T1"\nflange_mm = "unknown"\n', encoding="utf-8"
    )
    with pytest.raises(InputError, match=r"cell.toml: key `capture.start_deg` .* is missing: the capture plan"):
        plan_run(scenario)


def test_seeds_and_scenarios_of_the_wrong_type_are_refused_up_front(tmp_path):
    """A float or a string seed, or a Scenario object, is an InputError before anything runs (not a TypeError
    or a JSON error in a later stage); a numpy integer is an integer."""
    import numpy as np

    from robotcal.io import load_scenario

    for seed in (7.5, "7", np.random.default_rng(1)):
        with pytest.raises(InputError, match="seed must be an integer"):
            plan_run("kr5-demo", tmp_path / "out", seed=seed)
    plan = plan_run("kr5-demo", tmp_path / "out", seed=np.int64(7), draws=500)
    assert plan.seeds["capture"] == 7 and type(plan.seeds["capture"]) is int
    with pytest.raises(InputError, match="scenario name or TOML path; got Scenario"):
        plan_run(load_scenario("kr5-demo"))
    with pytest.raises(InputError, match=r"^--draws: "):
        plan_run("kr5-demo", draws=10)
    assert not (tmp_path / "out").exists()


def test_the_stage_tables_follow_the_stage_order():
    """OUTPUTS (hence RUN_ENTRIES and the report's table of stages) and STEPS list the stages in run order."""
    from robotcal.io.results.run_folder import OUTPUTS, RUN_ENTRIES, RUN_RECORD, STAGES
    from robotcal.pipeline.plan import STEPS

    assert tuple(OUTPUTS) == STAGES
    assert tuple(STEPS) == tuple(stage for stage in STAGES if stage in STEPS)
    assert RUN_ENTRIES[:5] == (RUN_RECORD, *OUTPUTS["simulate"])
    # the method's order (thesis ch. 4-5): identify, the joints (whose backlash the refinement corrects), refine
    # and evaluate, the uncertainty of the parameters, then of the TCP, the plan and its sensitivity, the ISO 9283
    # test, the report
    assert STAGES == (
        "simulate", "identify", "joints", "refine", "evaluate", "uncertainty", "tcp", "plan", "iso9283", "report",
    )  # fmt: skip
