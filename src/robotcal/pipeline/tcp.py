"""TCP uncertainty from Monte Carlo parameter draws (thesis ch. 5.3): the computation and the files of a TCP folder.

``robotcal tcp`` and the tcp stage of a run call :func:`compute_tcp` and :func:`write_tcp_folder`.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from robotcal.errors import InputError, JointLimitWarning
from robotcal.io.atomic import atomic_write_text
from robotcal.io.tcp_results import tcp_json_text, tcp_to_csv, tcp_to_dict
from robotcal.pipeline.figures import Render, draw_now, figure_paths
from robotcal.pipeline.folder import write_csv
from robotcal.pipeline.result import Document
from robotcal.uncertainty.tcp import TCPUncertainty, propagate_to_tcp
from robotcal.uncertainty.workspace import workspace_uncertainty

__all__ = ["TCP_MODES", "compute_tcp", "write_tcp_figures", "write_tcp_folder"]

#: Where the TCP uncertainty is stated: one pose, along a trajectory, over random workspace poses.
TCP_MODES = ("pose", "trajectory", "workspace")


def compute_tcp(
    robot,
    values: np.ndarray,
    mode: str,
    *,
    readings: np.ndarray | None = None,
    n_poses: int | None = None,
    seed: int = 0,
    tool_mm=None,
    coverage: float = 0.95,
):
    """TCP uncertainty of the draws ``values`` (n_draws, n_joints, 5) [mm, rad].

    ``mode`` ``"pose"`` or ``"trajectory"``: at ``readings`` (n_poses, n_joints) [rad], already checked
    against the limits (:func:`robotcal.uncertainty.tcp.check_readings`; the library's second warning is
    silenced); ``"workspace"``: at ``n_poses`` random poses within the limits drawn with ``seed``. Returns
    ``(TCPUncertainty, WorkspaceUncertainty or None)``.
    """
    if mode == "workspace":
        ws = workspace_uncertainty(robot, values, n_poses, rng=seed, tool=tool_mm, coverage=coverage)
        return ws.tcp, ws
    if mode not in ("pose", "trajectory"):
        raise InputError(f"unknown TCP mode {mode!r}: pose, trajectory or workspace")
    with warnings.catch_warnings():  # the caller has warned, naming the file
        warnings.simplefilter("ignore", JointLimitWarning)
        result = propagate_to_tcp(robot, values, readings, tool=tool_mm, coverage=coverage, keep_draws=mode == "pose")
    return result, None


def _write_tcp_json(path: Path, data: dict) -> dict:
    """Write ``tcp.json`` atomically (:func:`~robotcal.io.tcp_results.tcp_json_text`: indented, one pose per
    line); returns the document as :func:`~robotcal.pipeline.folder.read_run` reads it back."""
    text = tcp_json_text(data)
    atomic_write_text(path, text)
    # the poses of tcp_to_dict are plain JSON values already (lists of floats from tolist, str keys, None):
    # they read back equal, so only the small rest goes through the round trip (json.loads of a 1000-pose
    # workspace map costs about as much as writing it)
    return {key: value if key == "poses" else json.loads(json.dumps(value)) for key, value in data.items()}


def write_tcp_folder(
    folder: Path,
    result: TCPUncertainty,
    mode: str,
    *,
    interval: str = "symmetric",
    workspace=None,
    provenance: dict | None = None,
    figures: bool = True,
) -> dict[str, Document]:
    """Write ``tcp.csv``, ``tcp.json`` and (with ``figures``) the mode's figures into ``folder`` (an existing,
    normally temporary, folder); returns the documents by file name (CSV -> Table, JSON -> dict, figure -> Path).
    A run draws the figures later, in the background (:func:`write_tcp_figures`)."""
    documents: dict[str, Document] = {
        "tcp.csv": write_csv(folder / "tcp.csv", tcp_to_csv(result, interval=interval)),
        "tcp.json": _write_tcp_json(
            folder / "tcp.json",
            tcp_to_dict(result, interval=interval, workspace=workspace, provenance=provenance or {}),
        ),
    }
    if figures:
        for drawn in write_tcp_figures(folder, result, mode, workspace=workspace):
            documents.update({path.name: path for path in figure_paths(drawn)})
    return documents


def write_tcp_figures(folder: Path, result: TCPUncertainty, mode: str, *, workspace=None, render: Render = draw_now) -> list:
    """The figures of a TCP folder through ``render`` (:mod:`robotcal.pipeline.figures`): pose ->
    ``scatter.png``, ``histograms.png``; trajectory -> ``trajectory.png``; workspace -> ``workspace.png``.
    Returns what ``render`` returned, one item per figure."""
    folder = Path(folder)
    if mode == "pose":
        return [
            render("robotcal.plots.tcp:plot_tcp_scatter", result, folder / "scatter.png"),
            render("robotcal.plots.tcp:plot_tcp_histograms", result, folder / "histograms.png"),
        ]
    if mode == "trajectory":
        return [render("robotcal.plots.tcp:plot_trajectory", result, folder / "trajectory.png")]
    return [render("robotcal.plots.tcp:plot_workspace", workspace, folder / "workspace.png")]
