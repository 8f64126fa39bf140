"""pipeline.figures.FigureJobs: figures drawn in a process pool or at once, the same files; an error named."""

from __future__ import annotations

import pytest

from robotcal.errors import InputError
from robotcal.execution import process_pool
from robotcal.pipeline.figures import FigureJobs, draw_figure

THIS = "tests_figures_module"  # the module is imported under its file name by the pool's draw_figure


@pytest.mark.parametrize("workers", [0, 1])
def test_figures_are_drawn_and_their_paths_returned_in_order(tmp_path, workers, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / f"{THIS}.py").write_text(
        "from pathlib import Path\n"
        "def two(folder, stem):\n"
        "    paths = [Path(folder) / f'{stem}_{k}.txt' for k in range(2)]\n"
        "    [p.write_text('x') for p in paths]\n"
        "    return paths\n"
        "def one(path):\n"
        "    Path(path).write_text('y')\n"
        "    return str(path)\n"
    )
    (tmp_path / "out").mkdir()
    out = tmp_path / "out"
    if workers:
        with process_pool(workers) as pool:
            jobs = FigureJobs(pool)
            jobs.draw(f"{THIS}:two", out, "a")
            jobs.draw(f"{THIS}:one", out / "b.txt")
            paths = jobs.paths()
    else:
        jobs = FigureJobs()
        jobs.draw(f"{THIS}:two", out, "a")
        jobs.draw(f"{THIS}:one", out / "b.txt")
        paths = jobs.paths()
    assert [path.name for path in paths] == ["a_0.txt", "a_1.txt", "b.txt"]
    assert all(path.is_file() for path in paths)


def test_a_figure_error_names_the_plot_function(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / f"{THIS}_bad.py").write_text(
        "from robotcal.errors import InputError\n"
        "def bad(stem):\n"
        "    raise InputError(f'cannot draw {stem}: no space left')\n"
    )
    with process_pool(1) as pool:
        jobs = FigureJobs(pool)
        jobs.draw(f"{THIS}_bad:bad", "histograms")
        with pytest.raises(InputError, match="no space left") as caught:
            jobs.paths()
    assert any(f"{THIS}_bad:bad" in note for note in caught.value.__notes__)


def test_draw_figure_calls_the_named_function():
    assert draw_figure("math:hypot", 3.0, 4.0) == 5.0
