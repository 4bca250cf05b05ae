"""Every ```pvpython block of the README runs as written, from the project root, through the
project's pvpython launcher (paraview/pvpython), and prints its result."""

import os
import re
import subprocess

import pytest

from pvtools import ROOT

BLOCKS = re.findall(r"```pvpython\n(.*?)```", open(os.path.join(ROOT, "README.md")).read(), re.S)


def test_readme_has_a_pvpython_block():
    assert BLOCKS


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_pvpython_block_runs(index, tmp_path):
    script = tmp_path / f"block{index}.py"
    script.write_text(BLOCKS[index])
    env = dict(os.environ)
    env.pop("VIRTUAL_ENV", None)
    proc = subprocess.run([os.path.join(ROOT, "paraview", "pvpython"), str(script)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=300)
    lines = [ln for ln in proc.stdout.splitlines() if ln.strip()]
    assert proc.returncode == 0 and lines, (proc.stdout + proc.stderr)[-3000:]
