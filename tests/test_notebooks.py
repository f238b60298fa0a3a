"""The notebooks: committed with their outputs, and every code cell runs top to bottom
(in-process, sharing compiled scenes)."""
import json
import pathlib

import matplotlib
import pytest

NOTEBOOKS = sorted((pathlib.Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


def _code_cells(path):
    return [cell for cell in json.loads(path.read_text())["cells"] if cell["cell_type"] == "code"]


@pytest.mark.smoke
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_committed_executed_without_errors(path):
    """Executed in order (`jupyter nbconvert --to notebook --execute --inplace`), the
    outputs kept (a cell that prints or draws shows it), none an error; under 1 MB."""
    cells = _code_cells(path)
    assert [cell["execution_count"] for cell in cells] == list(range(1, len(cells) + 1))
    for cell in cells:
        source = "".join(cell["source"])
        if "print(" in source or "fig" in source:
            assert cell["outputs"], f"a cell that prints or draws shows it: {source[:60]!r}"
    kinds = [output["output_type"] for cell in cells for output in cell["outputs"]]
    assert "error" not in kinds
    assert any(kind in ("display_data", "execute_result") for kind in kinds), "a figure or a value is shown"
    assert path.stat().st_size < 1_000_000


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path):
    matplotlib.use("Agg")
    namespace: dict = {}
    for cell in _code_cells(path):
        exec(compile("".join(cell["source"]), f"{path.name}", "exec"), namespace)


@pytest.mark.smoke
def test_there_is_a_notebook():
    assert NOTEBOOKS
