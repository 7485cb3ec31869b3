"""The ```python blocks of README.md and docs/*.md run as written.

A file's blocks run in order in one fresh Python process, as a reader would run them: the test of
block N runs the file's runnable blocks up to and including N. The working directory is an empty
temporary folder (the data the docs read ships with the package), so nothing is written into the
repository.

Convention for blocks that are not meant to run (a fragment using the reader's own data, an API
summary, a long run): an HTML comment on the line right before the fence, which the rendered
page and the mkdocs site do not show::

    <!-- not-run: needs your robot's poses and scans -->
    ```python
    ...
    ```

Such a block is skipped here with its reason (``pytest -rs`` lists them) and left out of the
later blocks' runs. A block that takes more than a few seconds is marked ``<!-- not-run: slow -->``.
"""

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^([ \t]*)```python[ \t]*\n(.*?)^\1```[ \t]*$", re.S | re.M)
NOT_RUN = re.compile(r"^[ \t]*<!--[ \t]*not-run:[ \t]*(.*?)[ \t]*-->[ \t]*$")

# Runs the blocks given as JSON [[file, first code line, code], ...] on stdin in one namespace;
# the code is compiled under the Markdown file's name and line numbers, so a traceback points there.
DRIVER = """
import json, sys
namespace = {"__name__": "__main__", "__doc__": None}
for path, line, code in json.load(sys.stdin):
    exec(compile("\\n" * (line - 1) + code, path, "exec"), namespace)
"""


def _blocks():
    """``(file, first code line, code, not-run reason or None)`` of every python block."""
    out = []
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for m in FENCE.finditer(text):
            fence_line = text.count("\n", 0, m.start()) + 1
            before = text[: m.start()].split("\n")
            previous = before[-2] if len(before) >= 2 else ""
            reason = NOT_RUN.match(previous)
            code = textwrap.dedent(m.group(2))
            out.append((path, fence_line + 1, code, reason.group(1) if reason else None))
    return out


BLOCKS = _blocks()


def _id(block) -> str:
    path, line, _, _ = block
    return f"{path.relative_to(ROOT)}:{line - 1}"


def test_every_python_block_is_found_and_every_marker_has_a_block():
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        found = [b for b in BLOCKS if b[0] == path]
        assert len(found) == text.count("```python"), f"{path.name}: a ```python fence the parser missed"
        lines = text.split("\n")
        for i, line in enumerate(lines):
            if "not-run" in line:
                assert NOT_RUN.match(line), f"{path.name}:{i + 1}: write <!-- not-run: reason -->"
                assert NOT_RUN.match(line).group(1), f"{path.name}:{i + 1}: the not-run marker needs a reason"
                assert i + 1 < len(lines) and lines[i + 1].strip() == "```python", (
                    f"{path.name}:{i + 1}: a not-run marker must be on the line right before a ```python fence"
                )
    assert sum(reason is None for *_, reason in BLOCKS) >= 5


@pytest.mark.parametrize("index", range(len(BLOCKS)), ids=[_id(b) for b in BLOCKS])
def test_doc_python_block_runs(index, tmp_path):
    path, _, _, reason = BLOCKS[index]
    if reason is not None:
        pytest.skip(f"{_id(BLOCKS[index])} not-run: {reason}")
    # the file's runnable blocks up to this one, in order
    run = [[str(p), n, code] for p, n, code, r in BLOCKS[: index + 1] if p == path and r is None]
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run(
        [sys.executable, "-c", DRIVER],
        input=json.dumps(run),
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, f"{_id(BLOCKS[index])} failed:\n{proc.stderr[-4000:]}"


EXTRA = re.compile(r"--extra\s+'(\{.*?\})'", re.S)
ANY_FENCE = re.compile(r"^[ \t]*```.*?^[ \t]*```", re.S | re.M)


def documented_variant_problems(text: str, newest, versions) -> list[str]:
    """Problems of the ``--extra '{...}'`` relocalizer variants in a Markdown ``text``: JSON that does not parse, a
    variant no registered version's relocalizer (``versions``) takes, and a variant in a fenced block (a command
    meant to run as written) that the newest env's relocalizer (``newest``) refuses."""
    import semreloc_env
    from agents.relocalizer_eval import variant_parts
    from filters.localization.mcl import check_overrides

    def takes(base, overrides) -> bool:
        try:
            check_overrides(overrides, "variant", base)
        except ValueError:
            return False
        return True

    fences = [m.span() for m in ANY_FENCE.finditer(text)]
    problems = []
    for m in EXTRA.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        try:
            variants = json.loads(m.group(1))
        except json.JSONDecodeError as e:
            problems.append(f"line {line}: not JSON ({e})")
            continue
        for name, variant in variants.items():
            env_id, overrides = variant_parts(variant)
            if env_id:  # runs in that version: its relocalizer must take the overrides
                try:
                    base = semreloc_env.default_relocalizer(env_id)
                except ValueError:
                    problems.append(f"line {line}: variant {name} names no SemReloc id ({env_id!r})")
                    continue
                if not takes(base, overrides):
                    problems.append(f"line {line}: variant {name} does not fit {env_id}'s relocalizer")
                continue
            if not any(takes(base, overrides) for base in versions):
                problems.append(f"line {line}: variant {name} fits no registered version")
            elif any(a <= m.start() < b for a, b in fences) and not takes(newest, overrides):
                problems.append(f"line {line}: variant {name} (a command block) fails on the newest env")
    return problems


@pytest.mark.parametrize("path", DOCS, ids=lambda p: p.name)
def test_documented_relocalizer_variants_run(path):
    """The relocalizer variants the docs' commands pass (``evaluate_relocalizer --extra``) are valid: some
    registered version takes each, and the newest takes those of command blocks, which run as written (a
    review found three that a new version's option refused)."""
    import semreloc_env

    ids = semreloc_env.semreloc_ids_since(2)
    versions = [semreloc_env.default_relocalizer(i) for i in ids]
    assert documented_variant_problems(path.read_text(), versions[0], versions) == []


def test_documented_variant_check_finds_what_it_looks_for():
    import semreloc_env

    newest = semreloc_env.default_relocalizer(semreloc_env.semreloc_ids_since(2)[0])
    text = """```bash
x --extra '{"v4": {"audit_window": 0, "audit_after_surprise": false, "audit_after_surprise_once": false}}'
```
prose: --extra '{"v5": {"no_such_field": 1}}' and --extra '{"v6": {"audit_window": 0,}}'
and --extra '{"old": {"env_id": "SemReloc-v15", "lost_hold_window": 5}, "v18": {"env_id": "SemReloc-v18"}}'
and --extra '{"none": {"env_id": "SemReloc-v99"}}'
"""
    problems = documented_variant_problems(text, newest, [newest, semreloc_env.default_relocalizer("SemReloc-v15")])
    assert [p.split(":")[0] for p in problems] == ["line 2", "line 4", "line 4", "line 5", "line 6"]
    assert "fails on the newest" in problems[0] and "fits no" in problems[1] and "not JSON" in problems[2]
    assert "old does not fit SemReloc-v15's relocalizer" in problems[3] and "names no SemReloc id" in problems[4]
