"""read_run: the one reader of a run folder. Documents by kind, problems instead of exceptions, no links
followed, nothing outside the folder read; and the writer returns what the reader reads back."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from robotcal.errors import InputError
from robotcal.io.results.run_folder import (
    RunResult,
    Table,
    read_document,
    read_run,
    refusal,
    table_from_text,
    write_csv,
    write_json,
)

RECORD = {"command": "robotcal run kr5-demo", "status": "done", "stages": {"simulate": {"status": "done"}}}


def _folder(root: Path) -> Path:
    """A small hand-made run folder: run.json, a CSV, a JSON in a stage folder, a figure."""
    root.mkdir()
    (root / "run.json").write_text(json.dumps(RECORD), encoding="utf-8")
    (root / "capture.csv").write_text("circle,direction,q1,x\n1,1,0.5,1.25\n\n1,-1,0.75, 2\n", encoding="utf-8")
    (root / "cpa").mkdir()
    (root / "cpa" / "parameters.json").write_text('{"robot": "r", "joints": [1.5, 2]}', encoding="utf-8")
    (root / "uncertainty").mkdir()
    (root / "uncertainty" / "hist_J1.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    return root


def test_documents_by_kind(tmp_path):
    root = _folder(tmp_path / "run")
    result = read_run(root)
    assert isinstance(result, RunResult) and result.folder == root and result.problems == ()
    assert result.record == RECORD
    assert result.json("cpa/parameters.json") == {"robot": "r", "joints": [1.5, 2]}
    # cells exactly as written (" 2" keeps its space), blank records skipped
    assert result.table("capture.csv") == Table(
        header=("circle", "direction", "q1", "x"), rows=(("1", "1", "0.5", "1.25"), ("1", "-1", "0.75", " 2"))
    )
    assert result.file("uncertainty/hist_J1.png") == root / "uncertainty" / "hist_J1.png"
    assert sorted(result.documents) == ["capture.csv", "cpa/parameters.json", "run.json", "uncertainty/hist_J1.png"]
    assert result.summary is not None and result.results == {}


def test_files_that_are_not_the_runs_are_not_read(tmp_path):
    root = _folder(tmp_path / "run")
    (root / "notes.json").write_text("not json at all", encoding="utf-8")  # the user's, not a run output
    (root / "cpa" / ".parameters.json.tmp").write_text("{", encoding="utf-8")  # an atomic write's temporary
    result = read_run(root)
    assert "notes.json" not in result.documents and result.problems == ()


def test_unreadable_files_become_problems(tmp_path):
    root = _folder(tmp_path / "run")
    (root / "cpa" / "parameters.json").write_text("{ broken", encoding="utf-8")
    (root / "validation.csv").write_text("a,b\n1,2,3\n", encoding="utf-8")
    (root / "truth.json").write_text("[1, 2]", encoding="utf-8")
    (root / "evaluation").mkdir()
    (root / "evaluation" / "evaluation.csv").write_bytes(b"a,b\n\xff\xfe,1\n")
    result = read_run(root)
    problems = "\n".join(result.problems)
    assert "cpa/parameters.json: not a readable JSON file" in problems
    assert "validation.csv: row 2 has 3 cells; the header has 2" in problems
    assert "truth.json: expected a JSON object at the top level" in problems
    assert "evaluation/evaluation.csv: not a UTF-8 text file" in problems
    assert len(result.problems) == 4
    for name in ("cpa/parameters.json", "validation.csv", "truth.json", "evaluation/evaluation.csv"):
        assert name not in result.documents
    assert result.table("capture.csv") is not None  # the rest is read


def test_symbolic_links_are_refused(tmp_path):
    outside = tmp_path / "secret.json"
    outside.write_text('{"password": "hunter2"}', encoding="utf-8")
    root = _folder(tmp_path / "run")
    (root / "truth.json").symlink_to(outside)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "tcp.csv").write_text("a\n1\n", encoding="utf-8")
    (root / "tcp").symlink_to(elsewhere, target_is_directory=True)
    (root / "joints").mkdir()
    (root / "joints" / "summary.csv").symlink_to(root / "capture.csv")  # a link even inside the folder
    result = read_run(root)
    assert "truth.json" not in result.documents and "tcp/tcp.csv" not in result.documents
    assert "joints/summary.csv" not in result.documents
    assert sorted(p.split(":")[0] for p in result.problems) == ["joints/summary.csv", "tcp", "truth.json"]
    assert all("refused: a symbolic link" in p for p in result.problems)
    assert "hunter2" not in repr(result)


def test_refusal_of_paths_outside_the_folder(tmp_path):
    root = _folder(tmp_path / "run")
    assert refusal(root, "capture.csv") is None
    assert refusal(root, "../secret.json") == "refused: resolves outside the run folder"
    with pytest.raises(InputError, match=r"\.\./secret\.json: refused"):
        read_document(root, "../secret.json")


def test_a_folder_that_is_no_run_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="run folder not found"):
        read_run(tmp_path / "missing")
    (tmp_path / "file").write_text("x", encoding="utf-8")
    with pytest.raises(InputError, match="not a folder"):
        read_run(tmp_path / "file")
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "other.txt").write_text("x", encoding="utf-8")
    with pytest.raises(InputError, match="no results found"):
        read_run(tmp_path / "empty")


def test_writer_returns_what_the_reader_reads(tmp_path):
    root = tmp_path / "run"
    root.mkdir()
    document = {"a": (1, 2.5), "b": {"c": None, "d": "é"}, "e": 1e-17}
    written = write_json(root / "run.json", document)
    assert written == {"a": [1, 2.5], "b": {"c": None, "d": "é"}, "e": 1e-17}  # a tuple is read back a list
    assert read_document(root, "run.json") == written
    text = 'x,"y, with comma",z\n1,"two\nlines",3\n'
    table = write_csv(root / "capture.csv", text)
    assert table == read_document(root, "capture.csv")
    assert table.rows == (("1", "two\nlines", "3"),) and table.column("y, with comma") == ("two\nlines",)
    assert table_from_text("") == Table(header=())
    with pytest.raises(ValueError):
        write_json(root / "bad.json", {"x": float("nan")})  # strict JSON: no NaN written
    assert not (root / "bad.json").exists()


@pytest.mark.parametrize(
    ("cells", "numeric"),
    [
        (["1", " 2.5 ", "-3e-4", ""], True),
        (["", "  "], False),  # no number at all
        (["1", "x"], False),
        (["nan", "inf"], True),  # float() reads them: the report shows them as they are
        (["1,5"], False),  # a decimal comma is text
    ],
)
def test_a_table_knows_its_numeric_columns(cells, numeric):
    table = Table(header=("value",), rows=tuple((cell,) for cell in cells))
    assert table.numeric == (numeric,)
