"""io.results.tcp_results.write_tcp_folder: the documents it returns are the files as read back."""

from __future__ import annotations

import json

import numpy as np

from robotcal.api import workspace_uncertainty
from robotcal.io import load_robot
from robotcal.io.results.run_folder import table_from_text
from robotcal.io.results.tcp_results import write_tcp_folder

ROBOT = load_robot("kuka-kr5-sixx-r650-krc")


def test_returned_documents_equal_the_files_read_back(tmp_path):
    rng = np.random.default_rng(3)
    draws = ROBOT.nominal[None] + rng.normal(0.0, 1e-3, (40, ROBOT.n_joints, 5)) * ~ROBOT.structurally_fixed
    workspace = workspace_uncertainty(ROBOT, draws, 5, rng=2)
    provenance = {"mode": "workspace", "seconds": 0.5, "versions": {"numpy": np.__version__}}
    documents = write_tcp_folder(tmp_path, workspace.tcp, workspace=workspace, provenance=provenance)
    assert set(documents) == {"tcp.csv", "tcp.json"}
    assert documents["tcp.json"] == json.loads((tmp_path / "tcp.json").read_text())
    assert documents["tcp.json"]["workspace"]["poses"] == 5 and len(documents["tcp.json"]["poses"]) == 5
    assert documents["tcp.csv"] == table_from_text((tmp_path / "tcp.csv").read_text())
