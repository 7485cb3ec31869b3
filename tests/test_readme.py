"""The README's Python examples run as written (so the first thing a user copies works)."""

import re
import textwrap
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), re.S)


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 2


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_python_example_runs(index):
    code = textwrap.dedent(BLOCKS[index])
    exec(compile(code, f"README.md python block {index}", "exec"), {"__name__": "__readme__"})
