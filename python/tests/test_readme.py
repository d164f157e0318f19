"""The README's notebook example, run as written (from the repository root, figures drawn with
matplotlib's Agg backend): it needs the ``notebook`` extra (matplotlib), which .ci/run installs."""
import os
import re
import subprocess
import sys

import pytest

from conftest import ROOT


def readme_block(after: str) -> str:
    text = (ROOT / "README.md").read_text()
    start = text.index(after)
    return re.search(r"```python\n(.*?)```", text[start:], re.S).group(1)


def test_the_readme_notebook_example_runs():
    pytest.importorskip("matplotlib")
    code = readme_block("The bundled pair in a notebook")
    env = dict(os.environ, MPLBACKEND="Agg")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    m = re.search(r"mean error ×100 ([0-9.]+)", out.stdout)
    assert m and float(m.group(1)) < 2.0, out.stdout
