"""Every ```python block of the README and of the user guide (docs/guide.md) runs as written
(from the project root), so the tour the README shows and the guide's examples cannot rot."""

import os
import re

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
DOCS = ("README.md", "docs/guide.md")
BLOCKS = {doc: re.findall(r"```python\n(.*?)```", open(os.path.join(ROOT, doc)).read(), re.S) for doc in DOCS}


def test_readme_has_the_tour():
    assert len(BLOCKS["README.md"]) >= 4
    assert len(BLOCKS["docs/guide.md"]) >= 6  # one example per task of the guide


@pytest.mark.parametrize("doc, index", [(doc, i) for doc in DOCS for i in range(len(BLOCKS[doc]))])
def test_readme_block_runs(doc, index, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    os.makedirs("out", exist_ok=True)
    exec(compile(BLOCKS[doc][index], f"{doc} python block {index}", "exec"), {"__name__": "__readme__"})
    assert capsys.readouterr().out.strip(), "every README block prints its result"
