"""Run a planned calibration: every stage into one run folder, and a :class:`RunResult` in memory.

:func:`run_calibration` runs :data:`~robotcal.io.results.run_folder.STAGES` in order (the functions of
:mod:`robotcal.pipeline.stages`), each writing its own files (docs/results.md); ``run.json`` is rewritten
atomically after every stage, so a failed stage leaves the earlier stages' outputs and a record of which
stage failed and why. The calibration capture is kept in memory exactly as its CSV file holds it (12
decimals), so ``robotcal identify DIR/capture.csv`` reproduces the run's CPA bit for bit.

Figures are drawn by one worker process (:func:`robotcal.execution.process_pool`) while the later stages
compute; the report, the last stage, waits for them (it embeds them) and is rendered once, from the
RunResult in memory, after the final record (status, total time) is known; ``report.html`` and then
``run.json`` are written after it.

An interrupt (Ctrl-C, or SIGTERM/SIGHUP turned into one by the command line) is recorded as the interruption of the
stage it lands in. One whose exception Python dropped (:func:`robotcal.errors.check_interrupt`) is raised again
when the next stage starts, when the figures are waited for, and before the report is written, so that the run
stops all the same; the figure pool then stops its figure at once (:func:`robotcal.execution.process_pool`).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import json
import shutil
import time
import warnings
from collections.abc import Callable
from pathlib import Path

from robotcal.errors import InputError, RobotcalError, Terminated, check_interrupt, interrupt_behind
from robotcal.execution import process_pool
from robotcal.io.atomic import atomic_write_text, describe_os_error
from robotcal.io.results.output import check_output_folder, output_lock, write_marker
from robotcal.io.results.provenance import versions
from robotcal.io.results.run_folder import OUTPUTS, RUN_RECORD, STAGES, Document, RunResult, json_text
from robotcal.io.results.run_summary import summarise
from robotcal.kinematics.model import ParameterSet
from robotcal.pipeline import stages
from robotcal.pipeline.figures import FigureJobs
from robotcal.pipeline.plan import RunPlan
from robotcal.report import html

__all__ = ["REPORT_NAME", "StageProgress", "run_calibration", "run_record"]

#: ``progress(stage, done, total, detail)``: ``done`` 0 with detail "running" when a stage starts, -1 when it
#: ends (detail: its one-line result), else the steps (or draws, of ``total``) done so far.
StageProgress = Callable[[str, int, int | None, str], None]
#: The report's file in the run folder.
REPORT_NAME = "report.html"


def run_calibration(plan: RunPlan, progress: StageProgress | None = None, *, figure_workers: int = 1) -> RunResult:
    """Run every stage of ``plan`` into ``plan.out``; returns the run in memory.

    Parameters
    ----------
    plan : RunPlan
        From :func:`robotcal.pipeline.plan_run`; ``plan.out`` must name the run folder (a plan without one
        is refused: the figures and the Monte Carlo draws are files, and the report embeds them).
    progress : callable, optional
        :data:`StageProgress`, called as stages advance (``robotcal run`` drives its display with it).
    figure_workers : int
        Processes drawing the figures while the stages compute; 0 draws each figure when it is asked for.

    Returns
    -------
    RunResult
        ``record`` (``run.json``), ``documents`` (every file written), ``summary`` (headline figures),
        ``results``: the typed results, ``"truth"``, ``"nominal"``, ``"cpa"`` (ParameterSet), ``"cpa_result"``
        (CPAResult), ``"refined"`` (criterion -> RefinementResult), ``"capture"``, ``"validation"`` (Capture),
        ``"evaluation"`` (rows), ``"joints"`` (JointAnalysis), ``"montecarlo"`` (``"cpa"``/``"refined"`` ->
        MonteCarloResult), ``"tcp"`` (mode -> TCPUncertainty, with ``"workspace_map"`` and ``"consistency"``),
        ``"plan"`` (cell check and sensitivity study), ``"iso9283"`` (the simulated ISO 9283 study),
        ``"report"``.

    Raises
    ------
    InputError
        ``plan.out`` is None, or the folder was taken by another process since the plan was made.
    Exception
        A stage's error, after ``run.json`` recorded it; the exception carries ``robotcal_stage`` (the failed
        stage) and ``robotcal_record`` (the record as written).
    """
    if plan.out is None:
        raise InputError(
            "run_calibration needs a run folder: plan the run with plan_run(scenario, out=DIR) (its figures, "
            "Monte Carlo draws and report are files)"
        )
    with output_lock(plan.out):
        # checked again under the lock: another process may have written the folder since plan_run
        check_output_folder(plan.out, inputs=plan.inputs, force=plan.force, keeps_other_files=True)
        pool = process_pool(figure_workers) if figure_workers > 0 else contextlib.nullcontext(None)
        with pool as executor:
            return _Run(plan, progress, FigureJobs(executor)).execute()


def _scenario_echo(plan: RunPlan) -> dict:
    scenario = plan.scenario
    instrument = scenario.instrument
    return {
        "name": scenario.name,
        "source": scenario.source,
        "description": scenario.description,
        "robot": scenario.robot.name,
        "instrument": {
            "name": instrument.name,
            "a_um": instrument.a_mm * 1e3,
            "b_um_per_m": instrument.b_mm_per_m * 1e3,
            "noise": instrument.noise,
        },
        "settings": scenario.settings,
    }


def run_record(plan: RunPlan) -> dict:
    """``run.json`` before the first stage: command, scenario echo, seeds, settings, versions, stages pending."""
    return {
        "command": plan.command,
        "scenario": _scenario_echo(plan),
        "robot": plan.scenario.robot.name,
        "seed": plan.seeds["capture"],
        "seeds": dict(plan.seeds),
        "montecarlo": {
            "draws": plan.montecarlo.iterations,
            "coverage": plan.montecarlo.coverage,
            "workers": plan.montecarlo.workers,
            "simulated_robot": "the CPA result (cpa/parameters.json)",
        },
        "montecarlo_refined": {
            "draws": plan.refined_montecarlo.iterations,
            "model": "refined",
            "criterion": stages.DEPLOYED,
            "simulated_robot": "the refined result (refine/points.json)",
            "seed": "the same as montecarlo",
        },
        "tcp": {
            "pose": plan.tcp.pose_source,
            "trajectory": plan.tcp.trajectory_source,
            "workspace_poses": plan.tcp.workspace_poses,
            "workspace_draws": plan.tcp.workspace_draws,
            "workspace_seed": plan.seeds["workspace"],
            "tool_mm": None if plan.tcp.tool_mm is None else plan.tcp.tool_mm.tolist(),
        },
        "notes": list(plan.tcp.notes),
        "versions": versions(),
        "started": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "status": "running",
        "stages": {name: {"status": "pending", "seconds": None} for name in STAGES},
    }


def _status(exc: BaseException) -> str:
    return "interrupted" if interrupt_behind(exc) is not None else "failed"


def _message(exc: BaseException) -> str:
    exc = interrupt_behind(exc) or exc  # e.g. an import the interrupt broke: the interrupt is the reason
    if isinstance(exc, Terminated):  # SIGTERM or SIGHUP (robotcal.cli installs the handlers)
        return f"terminated ({exc.signal_name})"
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted (SIGINT, Ctrl-C)"
    message = str(exc) if isinstance(exc, RobotcalError) else f"{type(exc).__name__}: {exc}"
    notes = getattr(exc, "__notes__", None) or ()  # e.g. the figure that failed
    return " ".join([message, *map(str, notes)])


def _clear_previous(out: Path) -> None:
    """Remove the outputs of an earlier run into ``out`` (only the names a run writes)."""
    for names in OUTPUTS.values():
        for name in names:
            path = out / name
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path)
            elif path.exists() or path.is_symlink():
                path.unlink()
    (out / RUN_RECORD).unlink(missing_ok=True)


def _no_progress(stage: str, done: int, total: int | None, detail: str = "") -> None:
    """The progress of a run nobody watches."""


class _Run:
    """One execution of a plan: the record, the documents and typed results gathered stage by stage."""

    def __init__(self, plan: RunPlan, progress: StageProgress | None, figures: FigureJobs):
        assert plan.out is not None  # run_calibration refuses a plan without a folder
        self.plan = plan
        self.out: Path = plan.out
        self.progress: StageProgress = progress or _no_progress
        self.record: dict = {}
        self.documents: dict[str, Document] = {}
        self.results: dict = {}
        self.figures = figures
        self.started = time.perf_counter()

    def write_record(self) -> None:
        atomic_write_text(self.out / RUN_RECORD, json_text(self.record, default=str))

    def step(self, stage: str) -> Callable[..., None]:
        return lambda done, total, detail="": self.progress(stage, done, total, detail)

    def execute(self) -> RunResult:
        out = self.out
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(f"--out {out}: cannot create the folder: {describe_os_error(exc)}") from None
        write_marker(out, command=self.plan.command, files=[RUN_RECORD, *(n for names in OUTPUTS.values() for n in names)])
        _clear_previous(out)
        self.record = json_copy(run_record(self.plan))  # plain JSON types: the record is run.json as read back
        self.write_record()
        try:
            for name in STAGES[:-1]:
                self._stage(name, getattr(self, f"_{name}"))
            return self._report()
        except BaseException as exc:
            if self.record["status"] == "running":  # interrupted between stages
                self.record.update(status=_status(exc), error=_message(exc))
                self.write_record()
            raise

    def _fail(self, name: str, exc: BaseException, started: float) -> None:
        message = _message(exc)
        self.record["stages"][name].update(
            status=_status(exc), seconds=round(time.perf_counter() - started, 3), error=message
        )
        self.record.update(
            status=_status(exc), failed_stage=name, error=message, seconds=round(time.perf_counter() - self.started, 3)
        )
        self.write_record()
        for attribute, value in (("robotcal_stage", name), ("robotcal_record", self.record)):
            try:
                setattr(exc, attribute, value)
            except AttributeError:
                pass

    def _stage(self, name: str, function: Callable[[], stages.StageOutput]) -> None:
        started = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:  # an interrupt as soon as run.json says "running" is this stage's
                self.record["stages"][name]["status"] = "running"
                self.write_record()
                self.progress(name, 0, None, "running")
                check_interrupt()  # one whose exception was dropped in an earlier stage
                output: stages.StageOutput = function()
            except BaseException as exc:
                self._fail(name, exc, started)
                raise
        self.documents.update(output.documents)
        messages = list(dict.fromkeys(str(w.message) for w in caught))
        self.record["stages"][name].update(
            status="done",
            seconds=round(time.perf_counter() - started, 3),
            outputs=[entry for entry in OUTPUTS[name] if (self.out / entry).exists()],
            detail=output.detail,
            **({"warnings": messages} if messages else {}),
        )
        self.write_record()
        self.progress(name, -1, None, output.detail)

    # the stages, in order: each calls its function of robotcal.pipeline.stages and keeps its typed result

    def _simulate(self) -> stages.StageOutput:
        output = stages.simulate_stage(self.plan.scenario, self.plan.seeds, self.out, self.step("simulate"))
        self.results.update(
            truth=output.value.truth,
            nominal=ParameterSet.nominal(self.plan.scenario.robot),
            capture=output.value.capture,
            validation=output.value.validation,
            poses=output.value.poses,
        )
        return output

    def _identify(self) -> stages.StageOutput:
        output = stages.identify_stage(self.plan.scenario, self.results["capture"], self.out)
        self.results.update(cpa=output.value.parameters, cpa_result=output.value)
        return output

    def _refine(self) -> stages.StageOutput:
        output = stages.refine_stage(
            self.plan.scenario, self.results["capture"], self.results["cpa"], self.out, self.step("refine"),
            poses=self.results["poses"], joints=self.results["joints"] if self.plan.backlash else None,
        )  # fmt: skip
        self.results["refined"] = output.value
        return output

    def _evaluate(self) -> stages.StageOutput:
        output = stages.evaluate_stage(
            self.plan.scenario,
            cpa=self.results["cpa"],
            refined=self.results["refined"],
            capture=self.results["capture"],
            validation=self.results["validation"],
            out=self.out,
            figures=self.figures,
        )
        self.results["evaluation"] = output.value
        return output

    def _joints(self) -> stages.StageOutput:
        output = stages.joints_stage(
            self.plan.scenario, self.results["capture"], backlash=self.plan.backlash, out=self.out, figures=self.figures
        )
        self.results["joints"] = output.value
        return output

    def _uncertainty(self) -> stages.StageOutput:
        output = stages.uncertainty_stage(
            self.plan.scenario,
            montecarlo=self.plan.montecarlo,
            refined_montecarlo=self.plan.refined_montecarlo,
            seed=self.plan.seeds["montecarlo"],
            cpa=self.results["cpa"],
            deployed=self.results["refined"][stages.DEPLOYED].parameters,
            out=self.out,
            figures=self.figures,
            step=self.step("uncertainty"),
            poses=self.results["poses"],
            joints=self.results.get("joints"),
            capture=self.results["capture"],
            refined=self.results["refined"][stages.DEPLOYED],
        )
        value = dict(output.value)
        # the deployed values: the refinement's estimate corrected for the bias its Monte Carlo measures
        self.results["deployed"] = value.pop("deployed", None)
        self.results["joint_errors"] = value.pop("joint_errors", None)
        self.results["montecarlo"] = value
        return output

    def _tcp(self) -> stages.StageOutput:
        output = stages.tcp_stage(
            self.plan.scenario,
            targets=self.plan.tcp,
            draws=self.results["montecarlo"]["refined"],
            validation=self.results["validation"],
            deployed=self._deployed(),
            estimate=self.results["refined"][stages.DEPLOYED].parameters,
            joint_errors=self.results.get("joint_errors"),
            workspace_seed=self.plan.seeds["workspace"],
            out=self.out,
            figures=self.figures,
            step=self.step("tcp"),
        )
        self.results["tcp"] = output.value
        return output

    def _deployed(self) -> ParameterSet:
        """The deployed values: the uncertainty stage's bias-corrected estimate, else the refinement's estimate."""
        deployed = self.results.get("deployed")
        return self.results["refined"][stages.DEPLOYED].parameters if deployed is None else deployed

    def _plan(self) -> stages.StageOutput:
        output = stages.plan_stage(
            self.plan.scenario,
            seed=self.plan.seeds["montecarlo"],
            draws=self.plan.montecarlo.iterations,
            out=self.out,
            figures=self.figures,
            step=self.step("plan"),
        )
        self.results["plan"] = output.value
        return output

    def _iso9283(self) -> stages.StageOutput:
        models = {
            "nominal": self.results["nominal"],
            "cpa": self.results["cpa"],
            "refined": self._deployed(),
        }
        output = stages.iso9283_stage(
            self.plan.scenario,
            truth=self.results["truth"],
            models=models,
            seed=self.plan.seeds["iso9283"],
            out=self.out,
            figures=self.figures,
        )
        self.results["iso9283"] = output.value
        return output

    def _report(self) -> RunResult:
        """The last stage: every figure waited for, the final record, the summary and the report, rendered once
        from memory. A figure that failed fails the report stage, its message naming the figure."""
        name = "report"
        started = time.perf_counter()
        try:  # an interrupt as soon as run.json says "running" is this stage's
            self.record["stages"][name]["status"] = "running"
            self.write_record()
            self.progress(name, 0, None, "running")
            check_interrupt()
            for path in self.figures.paths():
                self.documents[path.relative_to(self.out).as_posix()] = path
            now = time.perf_counter()
            self.record["stages"][name].update(
                status="done",
                seconds=round(now - started, 3),
                outputs=[REPORT_NAME],
                detail="rendered from the run in memory",
            )
            self.record.update(
                status="done",
                seconds=round(now - self.started, 3),
                finished=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            )
            record = json_copy(self.record)
            documents = {**self.documents, RUN_RECORD: record}
            summary = summarise(record, documents)
            result = RunResult(folder=self.out, record=record, documents=documents, summary=summary)
            report = html.render_report(result)
            check_interrupt()
            atomic_write_text(self.out / REPORT_NAME, report.html)
        except BaseException as exc:
            self.record["stages"][name].pop("outputs", None)
            self.record["stages"][name].pop("detail", None)
            self.record.pop("finished", None)
            self._fail(name, exc, started)
            raise
        self.write_record()
        self.progress(name, -1, None, f"{report.figures} figures")
        documents = {**documents, REPORT_NAME: self.out / REPORT_NAME}  # the rendered RunResult stays as it was
        self.results["report"] = report
        return RunResult(
            folder=self.out,
            record=record,
            documents=documents,
            summary=summary,
            results=dict(self.results),
        )


def json_copy(document: dict) -> dict:
    """``document`` as ``run.json`` holds it once written and read back (plain JSON types)."""
    return json.loads(json_text(document, default=str))
