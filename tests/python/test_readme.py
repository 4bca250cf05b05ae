"""Every ```python block of the README and of the user guide (docs/guide.md) runs as written
(from the project root), so the tour the README shows and the guide's examples cannot rot.

A block whose fence names a requirement after ``python`` runs only where it holds:
``python vtk-module`` needs the VTK module (matrixtree_vtk: VTK pipelines, OpenCL), ``python
pyvista-accessor`` needs pyvista's dataset accessors (pyvista 0.48+); plain ``python`` blocks run
in every environment, the pip one included.
"""

import os
import re

import pytest

import matrixtree

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DOCS = ("README.md", "docs/guide.md")
BLOCKS = {doc: re.findall(r"```python( [a-z0-9-]+)?\n(.*?)```", open(os.path.join(ROOT, doc)).read(), re.S)
          for doc in DOCS}
NEEDS = {"": None,
         "vtk-module": "the VTK module (matrixtree_vtk)" if matrixtree.EXTENSION != "matrixtree_vtk" else None,
         "pyvista-accessor": None if matrixtree.filters.HAS_ACCESSOR else "pyvista's dataset accessors (0.48+)"}


def test_readme_has_the_tour():
    assert len(BLOCKS["README.md"]) >= 4
    assert len(BLOCKS["docs/guide.md"]) >= 6  # one example per task of the guide
    assert {need.strip() for doc in DOCS for need, _ in BLOCKS[doc]} <= set(NEEDS)
    assert sum(not need for need, _ in BLOCKS["README.md"]) >= 3  # a tour that runs everywhere


@pytest.mark.parametrize("doc, index", [(doc, i) for doc in DOCS for i in range(len(BLOCKS[doc]))])
def test_readme_block_runs(doc, index, monkeypatch, capsys):
    need, code = BLOCKS[doc][index]
    missing = NEEDS[need.strip()]
    if missing:
        pytest.skip(f"this block needs {missing}")
    monkeypatch.chdir(ROOT)
    os.makedirs("out", exist_ok=True)
    exec(compile(code, f"{doc} python block {index}", "exec"), {"__name__": "__readme__"})
    assert capsys.readouterr().out.strip(), "every README block prints its result"
